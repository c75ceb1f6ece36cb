"""The mutation catalogue (benchmarks/mutants*.py) still applies to the tree: every edit's text
occurs exactly once in its file and the mutated file still compiles. A source change that moves
a mutant's text makes mutation.py report it as "DOES NOT APPLY" and score it as a survivor; this
catches that at the change instead of at the next mutation run."""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_mutant_still_applies_once():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from mutants import MUTANTS
        from mutation import apply
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    problems = []
    for m in MUTANTS:
        try:
            apply((ROOT / m.path).read_text(), m)
        except (ValueError, OSError) as exc:
            problems.append(str(exc)[:200])
    assert len(MUTANTS) > 300 and problems == [], "\n".join(problems)
