#!/usr/bin/python3
"""Checks MCAP files that lidartag wrote with Foxglove's own code, outside the project's tests.

Foxglove's MCAP reader (the `mcap` Python package of github.com/foxglove/mcap, `python/mcap`)
reads every record of each file with CRC validation, then every message again through the
summary; each message on a `foxglove.*` schema must validate against Foxglove's published JSON
schema (github.com/foxglove/schemas, `schemas/jsonschema`), and keys a schema does not know are
reported too (Foxglove would silently ignore a misspelled field).

    scripts/check_foxglove.py --mcap-python MCAP/python/mcap --schemas SCHEMAS/schemas/jsonschema \
        FILE.mcap...

Debian 12's python3 has neither `zstandard` nor `lz4`: stand-ins that run Debian's `zstd` and
`lz4` programs are put on the path when the modules are missing. Exit status 0 when every file
passes, 1 when one does not. Not part of the test command (it needs the two checkouts).
"""
import argparse
import base64
import json
import pathlib
import sys
import tempfile

ZSTD_SHIM = '''import subprocess
def decompress(data, max_output_size=0):
    return subprocess.run(["zstd", "-d", "-c", "-q"], input=data, capture_output=True,
                          check=True).stdout
'''
LZ4_SHIM = '''import subprocess
def decompress(data):
    return subprocess.run(["lz4", "-d", "-c", "-q"], input=data, capture_output=True,
                          check=True).stdout
'''


def install_shims(where):
    for module, text in (("zstandard", ZSTD_SHIM), ("lz4.frame", LZ4_SHIM)):
        try:
            __import__(module)
        except ImportError:
            path = where.joinpath(*module.split(".")).with_suffix(".py")
            path.parent.mkdir(parents=True, exist_ok=True)
            if path.parent != where:
                (path.parent / "__init__.py").touch()
            path.write_text(text)
    sys.path.append(str(where))


def validate(value, schema, path, problems):
    """The JSON Schema keywords Foxglove's schemas use: type, properties, items, const, oneOf,
    minimum, maximum, contentEncoding (base64); plus unknown object keys."""
    if "oneOf" in schema:
        matches = [s for s in schema["oneOf"] if not check(value, s, path)]
        if len(matches) != 1:
            problems.append(f"{path}: {value!r} matches {len(matches)} of oneOf")
        return
    if "const" in schema and value != schema["const"]:
        problems.append(f"{path}: {value!r} is not {schema['const']!r}")
    kind = schema.get("type")
    is_number = isinstance(value, (int, float)) and not isinstance(value, bool)
    types = {"object": dict, "array": list, "string": str, "boolean": bool}
    if kind == "integer" and not (is_number and isinstance(value, int)):
        problems.append(f"{path}: {value!r} is not an integer")
        return
    if kind == "number" and not is_number:
        problems.append(f"{path}: {value!r} is not a number")
        return
    if kind in types and not isinstance(value, types[kind]):
        problems.append(f"{path}: a {type(value).__name__}, not {kind}")
        return
    if "minimum" in schema and value < schema["minimum"]:
        problems.append(f"{path}: {value} < {schema['minimum']}")
    if "maximum" in schema and value > schema["maximum"]:
        problems.append(f"{path}: {value} > {schema['maximum']}")
    if schema.get("contentEncoding") == "base64":
        try:
            base64.b64decode(value, validate=True)
        except ValueError as e:
            problems.append(f"{path}: not base64 ({e})")
    if kind == "object":
        known = schema.get("properties", {})
        for key, item in value.items():
            if key not in known:
                problems.append(f"{path}.{key}: not in Foxglove's schema")
            else:
                validate(item, known[key], f"{path}.{key}", problems)
    if kind == "array" and "items" in schema:
        for i, item in enumerate(value):
            validate(item, schema["items"], f"{path}[{i}]", problems)


def check(value, schema, path):
    problems = []
    validate(value, schema, path, problems)
    return problems


def check_file(path, schemas_dir):
    from mcap.reader import make_reader
    from mcap.stream_reader import StreamReader

    with open(path, "rb") as f:  # every record, chunks decompressed, every CRC checked
        records = sum(1 for _ in StreamReader(f, skip_magic=False, validate_crcs=True).records)
    counts, problems = {}, []
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        if summary is None:
            problems.append("no summary section")
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            key = (channel.topic, schema.name, schema.encoding, channel.message_encoding)
            counts[key] = counts.get(key, 0) + 1
            data = json.loads(message.data)
            if schema.name.startswith("foxglove."):
                reference = schemas_dir / (schema.name.split(".", 1)[1] + ".json")
                if not reference.exists():
                    problems.append(f"{schema.name}: Foxglove has no such schema")
                    continue
                found = check(data, json.loads(reference.read_text()), channel.topic)
                problems += found[:3]
    total = sum(counts.values())
    stated = summary.statistics.message_count if summary and summary.statistics else None
    if stated != total:
        problems.append(f"Statistics say {stated} messages, {total} read")
    print(f"{path}: {records} records read with their CRCs; {total} messages, "
          f"{len(summary.chunk_indexes) if summary else 0} chunk indexes")
    for (topic, name, encoding, message_encoding), n in sorted(counts.items()):
        print(f"  {topic}: {n} x {name} ({encoding}, {message_encoding})")
    for p in problems[:20]:
        print(f"  PROBLEM {p}")
    print(f"  {'passed' if not problems else f'{len(problems)} problems'}")
    return not problems


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mcap-python", type=pathlib.Path, required=True,
                        help="foxglove/mcap's python/mcap folder (holds the mcap package)")
    parser.add_argument("--schemas", type=pathlib.Path, required=True,
                        help="foxglove/schemas' schemas/jsonschema folder")
    parser.add_argument("files", nargs="+", type=pathlib.Path)
    args = parser.parse_args()
    if not (args.mcap_python / "mcap" / "reader.py").exists():
        sys.exit(f"{args.mcap_python}: no mcap/reader.py (give foxglove/mcap's python/mcap)")
    if not (args.schemas / "PointCloud.json").exists():
        sys.exit(f"{args.schemas}: no PointCloud.json (give foxglove/schemas' schemas/jsonschema)")
    sys.path.insert(0, str(args.mcap_python))
    with tempfile.TemporaryDirectory() as shims:
        install_shims(pathlib.Path(shims))
        ok = [check_file(f, args.schemas) for f in args.files]
    sys.exit(0 if all(ok) else 1)


if __name__ == "__main__":
    main()
