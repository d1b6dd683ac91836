"""Compare what the fault and stop scenarios wrote under two versions of rig (issue 32).

    python benchmarks/scenario_dump_at.py OLD /tmp/before      # the scenarios as commit OLD writes them
    python benchmarks/scenario_dump_at.py NEW /tmp/after
    python benchmarks/scenario_dump_at.py OLD /tmp/before2     # the old version again
    python benchmarks/scenario_identity.py /tmp/before /tmp/after [--repeat /tmp/before2]

(A dump of this checkout as it is: `RIG_SCENARIO_DUMP=/tmp/after python -m pytest -p scenario_dump -n 0
tests/acquisition tests/cli/test_end_to_end.py`. A worktree of another commit must import as that commit:
benchmarks/source_tree.py says why and how.)

Each scenario's datasets (brdf.csv, dataset.json, events.jsonl, ...) and its captured terminal output are
compared line by line after masking what differs from run to run by nature: loopback ports, pseudo-terminal
names, temporary folders, wall-clock timestamps and durations. Rig times are not masked: the simulated rig's
clock is deterministic. Prints every scenario that differs, with its first differing lines; exit 1 if any.

A few scenarios are not deterministic by nature: a stop or a signal sent from a wall-clock thread lands
after a varying number of points. With `--repeat`, a second run of the old version, the files that differ
between the two old runs are compared on what must still hold: the story of the run (the sequence of event
kinds, repeats collapsed) for event streams, the keys for JSON files and the header for CSV files; a
file whose story itself varies between the two old runs (a signal after a random delay) is only listed.
"""

from __future__ import annotations

import argparse
import difflib
import json
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


def story(path: Path) -> list[str]:
    """What must hold of a file whose exact content varies from run to run (see the module docstring)."""
    text = path.read_text(errors="replace")
    if path.suffix == ".jsonl":
        kinds = [json.loads(line).get("event", "?") for line in text.splitlines() if line.strip()]
        return [k for i, k in enumerate(kinds) if i == 0 or k != kinds[i - 1]]
    if path.suffix == ".json":
        return sorted(json.loads(text))
    if path.suffix == ".csv":
        return text.splitlines()[:1]
    return []


def compare(before: Path, after: Path, noisy: frozenset[str] = frozenset(),
            unstable: frozenset[str] = frozenset()) -> list[str]:
    problems = []
    scenarios = sorted({p.name for p in before.iterdir()} | {p.name for p in after.iterdir()})
    for name in scenarios:
        files_a = {p.relative_to(before / name) for p in (before / name).rglob("*") if p.is_file()}
        files_b = {p.relative_to(after / name) for p in (after / name).rglob("*") if p.is_file()}
        for rel in sorted(files_a ^ files_b):
            problems.append(f"{name}: {rel} only in {'before' if rel in files_a else 'after'}")
        for rel in sorted(files_a & files_b):
            if f"{name}/{rel}" in unstable:
                continue
            if f"{name}/{rel}" in noisy:
                a, b = story(before / name / rel), story(after / name / rel)
            else:
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
    parser.add_argument("--repeat", type=Path, help="a second run of the old version: what varies by nature")
    args = parser.parse_args(argv)
    noisy = unstable = frozenset()
    if args.repeat is not None:
        noisy = frozenset(line.split(" differs")[0].replace(": ", "/", 1)
                          for line in compare(args.before, args.repeat) if " differs" in line.split("\n")[0])
        unstable = frozenset(f"{line.split(': ')[0]}/{line.split(': ')[1].split(' differs')[0]}"
                             for line in compare(args.before, args.repeat, noisy) if " differs" in line.split("\n")[0])
        print(f"{len(noisy)} files vary between two runs of the old version: compared on their story only")
        for item in sorted(unstable):
            print(f"  not compared, its story varies too: {item}")
    problems = compare(args.before, args.after, noisy, unstable)
    count = len([p for p in args.before.iterdir() if p.is_dir()])
    for line in problems:
        print(line)
    print(f"{count} scenarios compared: " + ("identical apart from ports and times" if not problems
                                              else f"{len(problems)} differences"))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
