#!/usr/bin/python3
"""Runs the examples printed in the docs and checks that the commands still print what the docs say.

    scripts/check_docs.py --bin BUILD/bin [FILE.md ...]     (default: README.md and docs/*.md)

Two kinds of example are checked:
- a fenced block whose lines start with "$ " (a command; a line ending in "\\" goes on) followed by
  the output the command prints (standard output and error). "..." in the output stands for any
  number of lines. Lines are compared word by word, so column widths do not matter; a count must
  be exact, a decimal number must match to the last digit the docs show (one unit of it either
  way: a machine's last rounding), except durations (a number followed by "ms"), which vary with the machine's load.
- a ```json block right after a comment "<!-- check: COMMAND -->": the command prints one JSON
  object per line; the block (its "..." elisions dropped) must match the line with the same
  "sequence": every key the docs show with its value (numbers to the digits shown, lists
  from the start), except "timing_ms".

Commands run in a scratch folder where build/bin is the --bin folder and pcaps/ and config/ are
the source tree's; /tmp/ in a command or its output is that scratch folder. Blocks whose commands
need a display or a running daemon (lidartag-spy, lidartagd) are left to their own tests.
Exit status 0 when every example matches, 1 otherwise (each mismatch printed).
"""
import argparse
import json
import pathlib
import re
import subprocess
import sys
import tempfile

SOURCE = pathlib.Path(__file__).resolve().parents[1]
NUMBER = re.compile(r"^[-+]?\d+(\.\d+)?$")
LEFT_TO_OTHER_TESTS = ("lidartag-spy", "lidartagd")


def examples(path):
    """Yields (line number, kind, commands, expected text) of each example in a Markdown file."""
    lines = path.read_text().splitlines()
    i = 0
    while i < len(lines):
        check = re.match(r"^<!-- check: (.*) -->$", lines[i])
        if check and i + 1 < len(lines) and lines[i + 1].startswith("```json"):
            end = lines.index("```", i + 2)
            yield i + 1, "json", [check.group(1)], "\n".join(lines[i + 2:end])
            i = end + 1
            continue
        if lines[i].startswith("```") and i + 1 < len(lines) and lines[i + 1].startswith("$ "):
            end = lines.index("```", i + 1)
            body = lines[i + 1:end]
            steps, k = [], 0
            while k < len(body):
                command = body[k][2:]
                while command.endswith("\\"):
                    k += 1
                    command = command[:-1] + " " + body[k].strip()
                k += 1
                output = []
                while k < len(body) and not body[k].startswith("$ "):
                    output.append(body[k])
                    k += 1
                steps.append((command, output))
            yield i + 1, "shell", steps, None
            i = end + 1
            continue
        i += 1


def digits(token):
    return len(token.split(".")[1]) if "." in token else 0


def same_word(expected, actual, next_expected):
    if expected == actual:
        return True
    if NUMBER.match(expected) and NUMBER.match(actual):
        if next_expected.startswith("ms"):
            return True  # a duration
        if "." not in expected:
            return False  # a count: exact
        return abs(float(expected) - float(actual)) <= 1.000001 * 10.0 ** -digits(expected)
    return False


def same_line(expected, actual):
    e, a = expected.split(), actual.split()
    if len(e) != len(a):
        return False
    return all(same_word(e[k], a[k], e[k + 1] if k + 1 < len(e) else "") for k in range(len(e)))


def match_lines(expected, actual):
    """Whether `actual` lines match `expected`, where an expected "..." matches any lines."""
    if not expected:
        return not actual
    if expected[0].strip() == "...":
        return any(match_lines(expected[1:], actual[k:]) for k in range(len(actual) + 1))
    return bool(actual) and same_line(expected[0], actual[0]) and match_lines(expected[1:],
                                                                             actual[1:])


def match_json(expected, actual, where, problems):
    if isinstance(expected, dict):
        if not isinstance(actual, dict):
            problems.append(f"{where}: the docs show an object, the command prints {actual!r}")
            return
        for key, value in expected.items():
            if key not in actual:
                problems.append(f"{where}.{key}: the docs show it, the command does not print it")
            elif key != "timing_ms":
                match_json(value, actual[key], f"{where}.{key}", problems)
    elif isinstance(expected, list):
        if not isinstance(actual, list) or len(actual) < len(expected):
            problems.append(f"{where}: the docs show {expected!r}, the command prints {actual!r}")
            return
        for k, value in enumerate(expected):
            match_json(value, actual[k], f"{where}[{k}]", problems)
    elif isinstance(expected, float) or (isinstance(expected, int) and isinstance(actual, float)):
        shown = repr(expected)
        if abs(expected - actual) > 1.000001 * 10.0 ** -digits(shown):
            problems.append(f"{where}: the docs show {shown}, the command prints {actual}")
    elif expected != actual:
        problems.append(f"{where}: the docs show {expected!r}, the command prints {actual!r}")


def run(command, scratch):
    command = command.replace("/tmp/", f"{scratch}/")
    done = subprocess.run(["/bin/bash", "-c", command + " 2>&1"], cwd=scratch,
                          capture_output=True, text=True, timeout=300)
    return done.stdout.replace(f"{scratch}/", "/tmp/")


def check_file(path, bin_dir, problems):
    checked = 0
    for line, kind, steps, text in examples(path):
        where = f"{path.relative_to(SOURCE) if path.is_relative_to(SOURCE) else path}:{line}"
        commands = [s if kind == "json" else s[0] for s in steps]
        if any(re.search(rf"\b{name}\b", c) for c in commands for name in LEFT_TO_OTHER_TESTS):
            continue
        with tempfile.TemporaryDirectory(prefix="lidartag-docs-") as scratch:
            (pathlib.Path(scratch) / "build").mkdir()
            (pathlib.Path(scratch) / "build" / "bin").symlink_to(bin_dir)
            for name in ("pcaps", "config"):
                (pathlib.Path(scratch) / name).symlink_to(SOURCE / name)
            if kind == "json":
                expected = json.loads(re.sub(r",\s*\.\.\.", "", text))
                out = run(steps[0], scratch)
                printed = [json.loads(l) for l in out.splitlines() if l.startswith("{")]
                same = [j for j in printed if j.get("sequence") == expected.get("sequence")]
                if not same:
                    problems.append(f"{where}: no line of `{steps[0]}` has sequence "
                                    f"{expected.get('sequence')}:\n{out[:2000]}")
                else:
                    match_json(expected, same[0], where, problems)
            else:
                for command, output in steps:
                    out = run(command, scratch).splitlines()
                    if not match_lines(output, out):
                        problems.append(f"{where}: `{command}` printed\n" + "\n".join(out[:60]) +
                                        "\n  where the docs show\n" + "\n".join(output))
        checked += 1
    return checked


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bin", required=True, type=pathlib.Path,
                        help="folder of the built programs (build/bin)")
    parser.add_argument("files", nargs="*", type=pathlib.Path)
    args = parser.parse_args()
    files = args.files or [SOURCE / "README.md", *sorted((SOURCE / "docs").glob("*.md"))]
    problems, checked = [], 0
    for path in files:
        checked += check_file(path.resolve(), args.bin.resolve(), problems)
    for p in problems:
        print(f"check_docs: {p}\n")
    print(f"check_docs: {checked} examples checked, {len(problems)} not as the docs show")
    return 1 if problems or checked == 0 else 0


if __name__ == "__main__":
    sys.exit(main())
