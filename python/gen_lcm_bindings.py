#!/usr/bin/python3
"""Writes the pybind11 bindings of the project's LCM types (lcmtypes/*.lcm) for the Python module.

Usage: gen_lcm_bindings.py OUTPUT.cpp TYPE.lcm...

For every struct it emits
  * a Python class over lcm-gen's C++ type (lidartag.lcmtypes.<name>): a read-only attribute per
    field (numbers, strings, nested messages; numeric arrays as numpy arrays, string and message
    arrays as lists), the constants as class attributes, and `fields` (the names, in order);
  * a check that walks an encoded message and refuses lengths it cannot hold, so that a corrupt
    array count is counted as malformed instead of making decode() allocate gigabytes;
and one table of the types by fingerprint, so that a log event is decoded by its hash whatever its
channel. The decoding itself is lcm-gen's. Knows the part of the LCM grammar the project uses:
primitive types, string, nested structs of the same package, fixed and variable arrays, consts.
"""
import re
import sys

PRIMITIVES = {
    "int8_t": 1, "int16_t": 2, "int32_t": 4, "int64_t": 8,
    "float": 4, "double": 8, "boolean": 1, "byte": 1,
}
INTEGERS = {"int8_t", "int16_t", "int32_t", "int64_t", "byte"}


class Member:
    def __init__(self, type_name, name, dims):
        self.type = type_name
        self.name = name
        self.dims = dims  # list of int (fixed) or str (another member's name)


class Struct:
    def __init__(self, package, name):
        self.package = package
        self.name = name
        self.members = []
        self.consts = []  # (type, name, value)


def parse(path):
    text = open(path, encoding="utf-8").read()
    text = re.sub(r"//[^\n]*", "", text)
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    package = ""
    match = re.search(r"\bpackage\s+([\w.]+)\s*;", text)
    if match:
        package = match.group(1)
    structs = []
    for match in re.finditer(r"\bstruct\s+(\w+)\s*\{(.*?)\}", text, flags=re.S):
        struct = Struct(package, match.group(1))
        for statement in match.group(2).split(";"):
            statement = " ".join(statement.split())
            if not statement:
                continue
            if statement.startswith("const "):
                const = re.match(r"const\s+(\w+)\s+(.*)$", statement)
                for item in const.group(2).split(","):
                    name, value = (part.strip() for part in item.split("="))
                    struct.consts.append((const.group(1), name, value))
                continue
            member = re.match(r"([\w.]+)\s+(\w+)\s*((?:\[\s*\w+\s*\])*)$", statement)
            if not member:
                sys.exit(f"{path}: cannot parse '{statement}'")
            dims = [int(d) if d.isdigit() else d
                    for d in re.findall(r"\[\s*(\w+)\s*\]", member.group(3))]
            type_name = member.group(1).split(".")[-1]
            struct.members.append(Member(type_name, member.group(2), dims))
        structs.append(struct)
    return structs


def cpp_type(struct):
    return f"::{struct.package.replace('.', '::')}::{struct.name}" if struct.package \
        else f"::{struct.name}"


def check_function(struct, by_name):
    """C++ that walks one encoded struct (without its hash) and checks every length fits."""
    lines = [f"bool plausible_{struct.name}(const uint8_t* p, size_t len, size_t& pos) {{"]
    # Integer members, read as they pass: the dimensions of later arrays.
    used = {d for m in struct.members for d in m.dims if isinstance(d, str)}
    counters = [m.name for m in struct.members
                if m.type in INTEGERS and not m.dims and m.name in used]
    lines += [f"  int64_t v_{name} = 0;" for name in counters]
    known = set()
    for m in struct.members:
        count = "1"
        for d in m.dims:
            if isinstance(d, int):
                factor = str(d)
            else:
                if d not in known:
                    sys.exit(f"{struct.name}.{m.name}: dimension {d} is not an integer member "
                             "declared before it")
                lines.append(f"  if (v_{d} < 0 || static_cast<uint64_t>(v_{d}) > len) return false;")
                factor = f"static_cast<uint64_t>(v_{d})"
            count = factor if count == "1" else f"{count} * {factor}"
        lines.append(f"  {{  // {m.name}")
        lines.append(f"    const uint64_t count = {count};")
        lines.append("    if (count > len) return false;")
        if m.type in PRIMITIVES:
            size = PRIMITIVES[m.type]
            lines.append(f"    if (count * {size} > len - pos) return false;")
            if m.name in counters:
                lines.append(f"    v_{m.name} = read_be(p + pos, {size});")
                known.add(m.name)
            lines.append(f"    pos += count * {size};")
        elif m.type == "string":
            lines.append("    for (uint64_t k = 0; k < count; ++k) {")
            lines.append("      if (len - pos < 4) return false;")
            lines.append("      const int64_t n = read_be(p + pos, 4);")
            lines.append("      pos += 4;")
            lines.append("      if (n < 0 || static_cast<uint64_t>(n) > len - pos) return false;")
            lines.append("      pos += static_cast<size_t>(n);")
            lines.append("    }")
        elif m.type in by_name:
            lines.append("    for (uint64_t k = 0; k < count; ++k)")
            lines.append(f"      if (!plausible_{m.type}(p, len, pos)) return false;")
        else:
            sys.exit(f"{struct.name}.{m.name}: unknown type {m.type}")
        lines.append("  }")
    lines.append("  return true;")
    lines.append("}")
    return "\n".join(lines)


def binding(struct, by_name):
    t = cpp_type(struct)
    lines = [f"  {{",
             f"    auto c = py::class_<{t}>(types, \"{struct.name}\");",
             "    c.def(py::init<>());"]
    for m in struct.members:
        getter = f"[](const {t}& m) -> py::object {{ return "
        if m.type in PRIMITIVES and not m.dims:
            if m.type == "boolean":
                value = f"py::bool_(m.{m.name} != 0)"
            else:
                value = f"py::cast(m.{m.name})"
        elif m.type == "string" or m.type in by_name:
            value = f"py::cast(m.{m.name})"
        elif m.type in PRIMITIVES:
            value = f"to_numpy(m.{m.name})"
        else:
            sys.exit(f"{struct.name}.{m.name}: unknown type {m.type}")
        lines.append(f"    c.def_property_readonly(\"{m.name}\", {getter}{value}; }});")
    for const_type, name, value in struct.consts:
        lines.append(f"    c.attr(\"{name}\") = {value};")
    names = ", ".join(f"\"{m.name}\"" for m in struct.members)
    lines.append(f"    c.attr(\"fields\") = py::make_tuple({names});")
    lines.append(f"    c.attr(\"fingerprint\") = {t}::getHash();")
    lines.append("  }")
    return "\n".join(lines)


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    out_path = sys.argv[1]
    structs = [s for path in sorted(sys.argv[2:]) for s in parse(path)]
    by_name = {s.name: s for s in structs}
    parts = [
        "// Generated by python/gen_lcm_bindings.py from lcmtypes/*.lcm. Do not edit.",
        "#include \"lcm_types.hpp\"",
        "",
    ]
    parts += [f"#include \"{s.package.replace('.', '/')}/{s.name}.hpp\"" for s in structs]
    parts += ["", "namespace lidartag::python {", "namespace {", ""]
    parts += [f"bool plausible_{s.name}(const uint8_t* p, size_t len, size_t& pos);"
              for s in structs]
    parts.append("")
    parts += [check_function(s, by_name) + "\n" for s in structs]
    parts.append("}  // namespace")
    parts.append("")
    parts.append("void bind_lcm_types(py::module_& types) {")
    parts += [binding(s, by_name) for s in structs]
    parts.append("}")
    parts.append("")
    parts.append("const std::vector<LcmType>& lcm_types() {")
    parts.append("  static const std::vector<LcmType> types = {")
    for s in structs:
        t = cpp_type(s)
        parts.append(f"      {{\"{s.name}\", {t}::getHash(), &decode_message<{t}>,")
        parts.append(f"       [](const uint8_t* p, size_t len, size_t& pos) {{")
        parts.append(f"         return plausible_{s.name}(p, len, pos); }}}},")
    parts.append("  };")
    parts.append("  return types;")
    parts.append("}")
    parts.append("")
    parts.append("}  // namespace lidartag::python")
    with open(out_path, "w", encoding="utf-8") as f:
        f.write("\n".join(parts) + "\n")


if __name__ == "__main__":
    main()
