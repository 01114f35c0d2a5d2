#!/usr/bin/env python3
"""The README's results table, kept equal to the default comparison's summary.md.

    python3 .ci/readme_table.py check DIR    # fails when the README's iteration columns differ
    python3 .ci/readme_table.py update DIR   # writes DIR/summary.md's table into the README
    python3 .ci/readme_table.py update --keep-times DIR

DIR is the output directory of `deepcontact compare` with its defaults (the README's main
command; `--no-plots` is enough). The table sits between the two marker comments below. `check`
compares the iteration columns (mean, median, capped steps), which are deterministic: same
seeds, same counts on any machine and thread count. `update --keep-times` takes every other
column from DIR but keeps the README's timing columns (the times of a quiet machine's run).
"""
import sys
from pathlib import Path

BEGIN = "<!-- results-table: begin"
END = "<!-- results-table: end -->"
CHECKED = ["mean_iterations", "median_iterations", "capped_steps"]
TIMES = ["warm_start_ms", "solve_ms", "step_ms", "speedup_vs_none", "speedup_vs_builtin"]
README = Path(__file__).resolve().parent.parent / "README.md"


def table_lines(text):
    """The lines of the first Markdown table in text."""
    lines = text.splitlines()
    start = next(i for i, l in enumerate(lines) if l.startswith("| warm_start |"))
    end = start
    while end < len(lines) and lines[end].startswith("|"):
        end += 1
    return lines[start:end]


def parse(lines):
    """(header, {warm_start: {column: cell}}, row order) of a table's lines."""
    cells = lambda l: [c.strip() for c in l.strip().strip("|").split("|")]
    head = cells(lines[0])
    rows = {}
    order = []
    for l in lines[2:]:
        row = dict(zip(head, cells(l)))
        rows[row["warm_start"]] = row
        order.append(row["warm_start"])
    return head, rows, order


def readme_block(text):
    """(before, table lines, after) of the README around the generated block."""
    b = text.index(BEGIN)
    b = text.index("\n", b) + 1
    e = text.index(END)
    return text[:b], [l for l in text[b:e].splitlines() if l.strip()], text[e:]


def main(argv):
    if len(argv) < 2 or argv[0] not in ("check", "update"):
        sys.exit(__doc__)
    keep_times = "--keep-times" in argv
    fresh_dir = Path([a for a in argv[1:] if not a.startswith("--")][0])
    fresh = table_lines((fresh_dir / "summary.md").read_text())
    text = README.read_text()
    before, block, after = readme_block(text)
    if argv[0] == "update":
        if keep_times:
            head, old, _ = parse(block)
            fhead, new, order = parse(fresh)
            if head != fhead:
                sys.exit("the README's columns differ from the fresh table's: update without --keep-times")
            for name in order:
                if name in old:
                    for c in TIMES:
                        new[name][c] = old[name][c]
            fresh = fresh[:2] + ["| " + " | ".join(new[n][c] for c in head) + " |" for n in order]
        README.write_text(before + "\n" + "\n".join(fresh) + "\n\n" + after)
        print(f"README.md: table of {fresh_dir / 'summary.md'} written ({len(fresh) - 2} rows)")
        return
    _, old, old_order = parse(block)
    _, new, new_order = parse(fresh)
    problems = []
    if old_order != new_order:
        problems.append(f"rows: README {old_order}, fresh run {new_order}")
    for name in new_order:
        for c in CHECKED:
            a = old.get(name, {}).get(c)
            if a != new[name][c]:
                problems.append(f"{name} {c}: README {a}, fresh run {new[name][c]}")
    if problems:
        print("README.md's results table differs from " + str(fresh_dir / "summary.md") + ":")
        print("\n".join("  " + p for p in problems))
        print("regenerate it: python3 .ci/readme_table.py update --keep-times " + str(fresh_dir))
        sys.exit(1)
    print(f"README.md's results table: iteration columns of {len(new_order)} rows agree with the fresh run")


if __name__ == "__main__":
    main(sys.argv[1:])
