"""What produced a result file: leonav version, git commit, command line, scenario hash.

`provenance(scenario_raw)` is the one dictionary every results writer puts under the
`provenance` key of its metrics.json / summary.json, so a results folder says which code
and which inputs made it. The CLI records its command line with `set_command_line`; a
Python caller gets `python <script> ...` (sys.argv) unless it sets its own.
"""
from __future__ import annotations

import functools
import hashlib
import json
import shlex
import subprocess
import sys
from pathlib import Path
from typing import Any, Mapping

_COMMAND_LINE: str | None = None


def set_command_line(argv: list[str], prog: str = "leonav") -> None:
    """Record the command line of this process (called once by the CLI)."""
    global _COMMAND_LINE
    _COMMAND_LINE = shlex.join([prog, *argv])


def command_line() -> str:
    return _COMMAND_LINE if _COMMAND_LINE is not None else shlex.join(["python", *sys.argv])


def version() -> str:
    """The package version: `leonav_runtime.__version__`, which a test keeps equal to pyproject's
    and to the installed metadata's (importlib.metadata itself costs ~25 ms of CPU to import, a
    tenth of a `leonav spp` run)."""
    from leonav_runtime import __version__

    return __version__


@functools.lru_cache(maxsize=1)
def git_commit() -> dict[str, Any] | None:
    """{'commit': sha, 'dirty': bool} of the source checkout this code runs from, or None
    (an installed wheel, git missing, or a surrounding repository that is not leonav's)."""
    return git_commit_of(Path(__file__).resolve().parents[1])   # the leonav_runtime/ package folder


def git_commit_of(package_dir: Path) -> dict[str, Any] | None:
    """The commit of leonav's own tree holding `package_dir`: only when the folder above the
    package has leonav's pyproject.toml and is the top of its git work tree, so a wheel
    installed inside some other repository (a venv in a project) reports no commit."""
    root = Path(package_dir).resolve().parent
    # the top of a git work tree holds `.git` (a folder, or a file in a linked work tree)
    if not (root / "pyproject.toml").is_file() or not (root / ".git").exists():
        return None
    try:   # one git process: the commit from the branch header, changed tracked files after it
        out = subprocess.run(["git", "status", "--porcelain=v2", "--branch", "--untracked-files=no"], cwd=root,
                             capture_output=True, text=True, timeout=5, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    lines = out.splitlines()
    sha = next((ln.split()[2] for ln in lines if ln.startswith("# branch.oid ") and len(ln.split()) == 3), "")
    dirty = any(ln and not ln.startswith("#") for ln in lines)
    return {"commit": sha, "dirty": dirty} if len(sha) == 40 else None


def version_text() -> str:
    """'leonav 0.1.0 (git abcdef123456[+dirty])' for `leonav --version`."""
    g = git_commit()
    tail = f" (git {g['commit'][:12]}{'+dirty' if g['dirty'] else ''})" if g else ""
    return f"leonav {version()}{tail}"


def scenario_hash(raw: Mapping[str, Any] | None) -> str | None:
    """SHA-256 of the scenario's content (canonical JSON: key order and TOML layout do not
    change it), or None without a scenario."""
    if raw is None:
        return None
    text = json.dumps(raw, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def provenance(scenario_raw: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The `provenance` entry of a metrics.json / summary.json."""
    g = git_commit()
    return {"leonav_version": version(), "git_commit": g["commit"] if g else None,
            "git_dirty": g["dirty"] if g else None, "command_line": command_line(),
            "scenario_sha256": scenario_hash(scenario_raw)}
