"""Compare what the fault and stop scenarios wrote under two versions of rig (issue 32).

    RIG_SCENARIO_DUMP=/tmp/before python -m pytest -p scenario_dump -n 0 tests/acquisition   # old version
    RIG_SCENARIO_DUMP=/tmp/after  python -m pytest -p scenario_dump -n 0 tests/acquisition   # new version
    python benchmarks/scenario_identity.py /tmp/before /tmp/after

Each scenario's datasets (brdf.csv, dataset.json, events.jsonl, ...) and its captured terminal output are
compared line by line after masking what differs from run to run by nature: loopback ports, pseudo-terminal
names, temporary folders, wall-clock timestamps and durations. Rig times are not masked: the simulated rig's
clock is deterministic. Prints every scenario that differs, with its first differing lines; exit 1 if any.
"""

from __future__ import annotations

import argparse
import difflib
import re
import sys
from pathlib import Path

MASKS = [
    (re.compile(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?(Z|[+-]\d\d:\d\d)?"), "<UTC>"),
    (re.compile(r"(127\.0\.0\.1|localhost)([:, ]+(port )?)\d+"), r"\1\2<PORT>"),
    (re.compile(r"\"port\": \d+"), "\"port\": <PORT>"),
    (re.compile(r"/dev/pts/\d+"), "/dev/pts/<N>"),
    (re.compile(r"/tmp/[^\s\"',)]*"), "<TMP>"),
    (re.compile(r"\"(wall_s|wall_time_s|pid|host|started_wall|ended_wall|elapsed_wall_s)\": [^,}\n]+"),
     r'"\1": <WALL>'),
    (re.compile(r"wall( time)? \d+(:\d\d)*(\.\d+)? ?s?"), "wall <WALL>"),
    (re.compile(r"pid \d+"), "pid <PID>"),
]


def masked(text: str) -> list[str]:
    for pattern, repl in MASKS:
        text = pattern.sub(repl, text)
    return text.splitlines()


def compare(before: Path, after: Path) -> list[str]:
    problems = []
    scenarios = sorted({p.name for p in before.iterdir()} | {p.name for p in after.iterdir()})
    for name in scenarios:
        files_a = {p.relative_to(before / name) for p in (before / name).rglob("*") if p.is_file()}
        files_b = {p.relative_to(after / name) for p in (after / name).rglob("*") if p.is_file()}
        for rel in sorted(files_a ^ files_b):
            problems.append(f"{name}: {rel} only in {'before' if rel in files_a else 'after'}")
        for rel in sorted(files_a & files_b):
            a = masked((before / name / rel).read_text(errors="replace"))
            b = masked((after / name / rel).read_text(errors="replace"))
            if a != b:
                diff = list(difflib.unified_diff(a, b, "before", "after", n=0, lineterm=""))[2:8]
                problems.append(f"{name}: {rel} differs\n    " + "\n    ".join(diff))
    return problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    args = parser.parse_args(argv)
    problems = compare(args.before, args.after)
    count = len([p for p in args.before.iterdir() if p.is_dir()])
    for line in problems:
        print(line)
    print(f"{count} scenarios compared: " + ("identical apart from ports and times" if not problems
                                              else f"{len(problems)} differences"))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
