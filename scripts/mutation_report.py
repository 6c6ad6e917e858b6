"""Per-module kill rates of the last mutation run (reads mutmut's mutants/**/*.py.meta).

Kill rate = (killed + timeout) / (killed + timeout + survived): a mutant that makes the tests hang is
detected too. Mutants that no selected test reaches ("no tests") are listed apart (code the GL-free
selection does not exercise), as are those not checked before the time box ended.
Usage: python scripts/mutation_report.py [--survivors] [MUTANTS_DIR]
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path

STATUS = {1: "killed", 3: "killed", 0: "survived", 5: "no tests", 33: "no tests", 34: "skipped", 36: "timeout",
          24: "timeout", -24: "timeout", 152: "timeout", 255: "timeout", -11: "segfault", -9: "segfault",
          None: "not checked"}


def main(argv: list[str]) -> int:
    show_survivors = "--survivors" in argv
    args = [a for a in argv if not a.startswith("--")]
    root = Path(args[0] if args else "mutants")
    rows, survivors = [], []
    for meta in sorted(root.rglob("*.py.meta")):
        codes = json.loads(meta.read_text())["exit_code_by_key"]
        if not codes:
            continue
        counts = Counter(STATUS.get(code, "suspicious") for code in codes.values())
        module = str(meta.relative_to(root))[: -len(".meta")]
        tested = counts["killed"] + counts["survived"] + counts["timeout"]
        rate = (counts["killed"] + counts["timeout"]) / tested if tested else float("nan")
        rows.append((module, len(codes), counts, rate))
        survivors += [name for name, code in codes.items() if STATUS.get(code) == "survived"]
    print(f"{'module':45} {'mutants':>7} {'killed':>6} {'survived':>8} {'timeout':>7} {'no tests':>8} "
          f"{'unchecked':>9} {'kill rate':>9}")
    total = Counter()
    for module, n, c, rate in rows:
        total.update(c)
        print(f"{module:45} {n:7d} {c['killed']:6d} {c['survived']:8d} {c['timeout']:7d} {c['no tests']:8d} "
              f"{c['not checked']:9d} {rate:9.1%}")
    tested = total["killed"] + total["survived"] + total["timeout"]
    if tested:
        print(f"{'all':45} {sum(r[1] for r in rows):7d} {total['killed']:6d} {total['survived']:8d} "
              f"{total['timeout']:7d} {total['no tests']:8d} {total['not checked']:9d} "
              f"{(total['killed'] + total['timeout']) / tested:9.1%}")
    if show_survivors:
        print("\nsurvivors (inspect with: .venv/bin/mutmut show NAME):")
        print("\n".join(survivors))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
