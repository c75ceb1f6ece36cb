"""Every command's --help speaks to the user: each argument described, numbers with their unit.

Walks the real parser (every command and sub-command), so a new option without a description,
a float option without a unit, or developer notes (module hooks, lint markers, source paths) in a
description fail here rather than in a newcomer's terminal.
"""
from __future__ import annotations

import argparse
import re

from leonav_runtime.cli import build_parser

# Words of the code base, not of the user: where a command is wired, lint markers, source paths.
DEVELOPER_TEXT = re.compile(r"\b(adapter|hook|noqa|register\(|import )|leonav_runtime/|\.py\b", re.I)
# A float option states what it is measured in (SI or the field's customary unit).
UNIT = re.compile(r"(\b(s|m|deg|rad|Hz|kHz|MHz|dB|dB-Hz|ppm|MB|days?|seconds?|S/s|Hz/s|m/s|m\^2/s\^3)\b)")
TEMPLATE = re.compile(r"%\(\w+\)[-#0 +]*\d*(\.\d+)?\w")  # argparse's %(default)g: not a unit


def _parsers(p: argparse.ArgumentParser, path: tuple[str, ...] = ("leonav",)):
    yield path, p
    for a in p._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sub in a.choices.items():
                yield from _parsers(sub, path + (name,))


def _arguments():
    for path, p in _parsers(build_parser()):
        for a in p._actions:
            if not isinstance(a, (argparse._HelpAction, argparse._SubParsersAction, argparse._VersionAction)):
                yield " ".join(path), "/".join(a.option_strings) or a.dest, a


def test_the_walk_reaches_every_command():
    commands = {path for path, _ in _parsers(build_parser())}
    assert {("leonav", "sweep"), ("leonav", "gnss", "obs"), ("leonav", "gnss", "tle-vs-brdc"),
            ("leonav", "tle", "builtin"), ("leonav", "nav")} <= commands
    assert len(commands) > 25


def test_every_argument_has_a_description():
    missing = [f"{cmd} {name}" for cmd, name, a in _arguments() if not (a.help and a.help.strip())]
    assert not missing, "arguments without help text: " + ", ".join(missing)


def test_every_float_option_states_its_unit():
    without = [f"{cmd} {name}: {a.help!r}" for cmd, name, a in _arguments()
               if a.type is float and a.help and not UNIT.search(TEMPLATE.sub("", a.help))]
    assert not without, "float options whose help names no unit:\n" + "\n".join(without)


def test_no_developer_text_in_help():
    found = []
    for path, p in _parsers(build_parser()):
        if path[:2] == ("leonav", "codegen"):
            continue  # the model developer's own command: source paths are its subject
        texts = [p.description or "", p.epilog or ""] + [a.help or "" for a in p._actions]
        for text in texts:
            if m := DEVELOPER_TEXT.search(text):
                found.append(f"{' '.join(path)}: {m.group(0)!r} in {text[:60]!r}")
    assert not found, "developer-facing text in --help:\n" + "\n".join(found)
