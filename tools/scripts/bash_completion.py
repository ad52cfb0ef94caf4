#!/usr/bin/python3
"""Writes a bash completion script for a CLI11 program from its own --help (and each
subcommand's), so that it never drifts from the options the program has.

usage: bash_completion.py PROGRAM NAME OUT

PROGRAM is the built executable, NAME the command the completion is for (lidartag, lidartagd).
What an option's value completes to follows from its type in the help text:
  {a,b,c}            one of the words (a type name or a CLI11 IsMember set)
  FAMILY             the tag family names in the option's description, and files
  FLOAT, INT, UINT, LENGTH, IDS, IPV4   nothing (a number or a value to type)
  anything else      file names (TEXT, TEXT:FILE, positionals)
"""
import re
import subprocess
import sys

NO_COMPLETION = {"FLOAT", "INT", "UINT", "LENGTH", "IDS", "IPV4", "NUMBER", "POSITIVE"}


def run_help(program, *args):
    return subprocess.run([program, *args, "--help"], check=True, capture_output=True,
                          text=True).stdout


def parse(help_text):
    """Options (names, type or None for a flag, description), positionals (type) and the
    subcommand names of one CLI11 help text."""
    options, positionals, subcommands = [], [], []
    section = None
    current = None
    for line in help_text.splitlines():
        if line and not line.startswith(" "):
            section = line.rstrip(":") if line.endswith(":") else None
            current = None
            continue
        stripped = line.strip()
        if not stripped:
            continue
        parts = re.split(r"\s{2,}", stripped, maxsplit=1)
        head, description = parts[0], parts[1] if len(parts) > 1 else ""
        if line.startswith("   ") and current is not None:
            # A wrapped description (CLI11 puts long option heads on their own line).
            current[2] += " " + stripped
            continue
        tokens = head.split(" ")
        if section == "Options" and tokens[0].startswith("-"):
            names = [n for n in tokens[0].split(",") if n.startswith("-")]
            kind = tokens[1] if len(tokens) > 1 and tokens[1] not in ("Excludes:", "Needs:",
                                                                         "REQUIRED") else None
            current = [names, kind, description]
            options.append(current)
        elif section == "Positionals":
            positionals.append((tokens[1] if len(tokens) > 1 else "TEXT", description))
            current = None
        elif section == "Subcommands":
            subcommands.append(tokens[0])
            current = None
    return options, positionals, subcommands


def value_words(kind, description):
    """('words', [...]), ('files', extra words) or ('none', [])."""
    if kind is None:
        return None
    base = re.sub(r"=.*$", "", kind)  # a default value after '='
    choice = re.search(r"\{([^}]*)\}", base)
    if choice:
        return ("words", [w for w in choice.group(1).split(",") if w])
    if base.startswith("FAMILY"):
        return ("files", family_words(description))
    # A description that is only a list of words ("trace, debug, info"): one of them.
    if base == "TEXT" and re.fullmatch(r"[\w-]+(, [\w-]+)+", description.strip()):
        return ("words", description.strip().split(", "))
    type_names = set(re.split(r"[:\s]", base))
    if type_names & NO_COMPLETION:
        return ("none", [])
    return ("files", [])


def family_words(description):
    """Tag family names mentioned in a description (tag16h5, ...), in order."""
    return list(dict.fromkeys(re.findall(r"\btag\w+", description)))


def quote(words):
    return " ".join(words)


def emit(name, commands):
    """commands: {subcommand or "": (options, positionals)}, "" being the top level."""
    func = "_" + re.sub(r"\W", "_", name)
    subs = [s for s in commands if s]
    out = [
        f"# bash completion for {name}. Generated from `{name} --help` by",
        "# tools/scripts/bash_completion.py at build time: do not edit.",
        f"{func}() {{",
        '  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD-1]} sub="" i',
    ]
    if subs:
        out += [
            "  for ((i = 1; i < COMP_CWORD; i++)); do",
            '    case "${COMP_WORDS[i]}" in',
            f"      {'|'.join(subs)}) sub=${{COMP_WORDS[i]}}; break ;;",
            "    esac",
            "  done",
        ]
    out += ['  case "$sub:$prev" in']
    for sub, (options, _) in commands.items():
        groups = {}
        for names, kind, description in options:
            completion = value_words(kind, description)
            if completion is None:
                continue
            groups.setdefault((completion[0], tuple(completion[1])), []).extend(names)
        for (mode, words), names in groups.items():
            pattern = "|".join(f"{sub}:{n}" for n in names)
            if mode == "words":
                action = f'COMPREPLY=($(compgen -W "{quote(words)}" -- "$cur"))'
            elif mode == "none":
                action = "COMPREPLY=()"
            elif words:
                action = (f'COMPREPLY=($(compgen -W "{quote(words)}" -- "$cur") '
                          f'$(compgen -f -- "$cur"))')
            else:
                action = 'COMPREPLY=($(compgen -f -- "$cur"))'
            out.append(f"    {pattern}) {action}; return ;;")
    out.append("  esac")
    out.append('  if [[ $cur == -* ]]; then')
    out.append('    case "$sub" in')
    for sub, (options, _) in commands.items():
        names = [n for names, _, _ in options for n in names]
        out.append(f'      "{sub}") COMPREPLY=($(compgen -W "{quote(names)}" -- "$cur")) ;;')
    out.append("    esac")
    out.append("    return")
    out.append("  fi")
    if subs:
        out.append('  if [[ -z $sub ]]; then')
        out.append(f'    COMPREPLY=($(compgen -W "{quote(subs)}" -- "$cur"))')
        out.append("    return")
        out.append("  fi")
    # Positionals: files (captures, scenes, family files), and the family names where a family
    # is expected.
    families = {sub: family_words(d) for sub, (_, positionals) in commands.items()
                for kind, d in positionals if kind.startswith("FAMILY")}
    if families:
        out.append('  case "$sub" in')
        for sub, words in families.items():
            out.append(f'    "{sub}") COMPREPLY=($(compgen -W "{quote(words)}" -- "$cur") '
                       f'$(compgen -f -- "$cur")); return ;;')
        out.append("  esac")
    out.append('  COMPREPLY=($(compgen -f -- "$cur"))')
    out.append("}")
    out.append(f"complete -o filenames -o bashdefault -F {func} {name}")
    return "\n".join(out) + "\n"


def main():
    program, name, path = sys.argv[1:4]
    top = parse(run_help(program))
    commands = {"": (top[0], top[1])}
    for sub in top[2]:
        options, positionals, _ = parse(run_help(program, sub))
        commands[sub] = (options, positionals)
    with open(path, "w") as f:
        f.write(emit(name, commands))


if __name__ == "__main__":
    main()
