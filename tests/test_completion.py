"""`leonav completion`: the generated bash script completes commands and options in a real
bash; the zsh script is a compdef for leonav."""
from __future__ import annotations

import shutil
import subprocess

import pytest

from leonav_runtime.cli import main


def _script(shell: str, capsys) -> str:
    assert main(["completion", shell]) == 0
    return capsys.readouterr().out


def _bash_complete(script_path, words: list[str]) -> list[str]:
    line = " ".join(words)
    cmd = (f"source {script_path}; COMP_WORDS=({line}); COMP_CWORD={len(words) - 1}; COMP_LINE='{line}'; "
           f"COMP_POINT={len(line)}; _shtab_leonav leonav '{words[-1]}' '{words[-2]}'; printf '%s\\n' \"${{COMPREPLY[@]}}\"")
    run = subprocess.run(["bash", "-c", cmd], capture_output=True, text=True, timeout=20)
    return run.stdout.split()


def test_bash_completion_completes_commands_and_options(tmp_path, capsys):
    if shutil.which("bash") is None:
        pytest.skip("needs bash to source the completion script; not found on PATH")
    path = tmp_path / "leonav.bash"
    path.write_text(_script("bash", capsys))
    assert _bash_complete(path, ["leonav", "sw"]) == ["sweep"]
    assert "--modes" in _bash_complete(path, ["leonav", "sweep", "--mo"])
    assert set(_bash_complete(path, ["leonav", "tle", "fetch", "--form"])) == {"--format"}


def test_zsh_script_is_a_compdef(capsys):
    text = _script("zsh", capsys)
    assert text.startswith("#compdef leonav") and "sweep" in text and "--counts" in text
