"""README.md stays a short usage page (issue 26): at most 350 lines, the two commands and the
job -> command index on its first screen, the test command identical to .ci/run's, and every
relative link in README.md and docs/*.md naming a file that exists."""
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
MAIN_COMMAND = "pip install . && leonav sweep"
TEST_COMMAND = "pip install -e '.[test]' && pytest -q -n auto"
JOBS = ("reproduce the paper", "study a parameter", "run a real dataset", "single-point GNSS",
        "live navigation on the Pi", "observability", "regenerate after a model change",
        "distributed sweep")
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")


def test_readme_is_at_most_350_lines():
    n = len(README.read_text().splitlines())
    assert n <= 350, f"README.md has {n} lines; move detail to docs/"


def test_first_40_lines_hold_the_two_commands_and_the_job_index():
    head = README.read_text().splitlines()[:40]
    text = "\n".join(head)
    assert any(line.startswith(MAIN_COMMAND) for line in head), "main-job command missing"
    assert any(line.startswith(TEST_COMMAND) for line in head), "test command missing"
    assert text.index(MAIN_COMMAND) < text.index("| job | command |"), "commands come before the index"
    rows = [line for line in head if line.startswith("| ")]
    assert rows and rows[0].startswith("| job | command | where documented |")
    for job in JOBS:
        row = next((r for r in rows if r.startswith(f"| {job} |")), None)
        assert row is not None, f"job index lacks a row for {job!r}"
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert len(cells) == 3 and "`" in cells[1] and "](" in cells[2], row


def test_readme_test_command_is_the_one_ci_runs():
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    marker = next(i for i, line in enumerate(ci) if "keep identical" in line)
    assert ci[marker + 1].strip() == TEST_COMMAND


def _relative_links(path: Path):
    text = re.sub(r"```.*?```", "", path.read_text(), flags=re.S)   # code blocks are not links
    for target in LINK.findall(text):
        if re.match(r"[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
            continue
        yield target.split("#", 1)[0]


def test_every_relative_link_points_to_an_existing_file():
    pages = [README, *sorted((ROOT / "docs").glob("*.md"))]
    broken = [f"{p.relative_to(ROOT)} -> {t}" for p in pages for t in _relative_links(p)
              if not (p.parent / t).exists()]
    assert not broken, broken
    assert sum(1 for _ in _relative_links(README)) >= 20   # the links are really being checked
