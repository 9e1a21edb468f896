"""docs/your_own_filter.md and docs/your_own_model.md are complete walk-throughs that run as
written: their copies of the example's files are the files, every ``console`` block's command
gives its exit status and shown lines (``...`` matches anything), every ``sh`` block runs, every
``python`` block runs (in document order; ``runs/`` is a temporary folder)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

try:
    from byo_example import EXAMPLE, example_fmus, uwcosim_env
except ImportError:  # pragma: no cover - run from the project root as a package
    from tests.byo_example import EXAMPLE, example_fmus, uwcosim_env

__all__ = ["example_fmus"]  # the fixture

ROOT = Path(__file__).resolve().parents[1]
DOCS = ["docs/your_own_filter.md", "docs/your_own_model.md"]
BLOCK = re.compile(r"(?:<!-- (?P<mark>[^>]*) -->\n)?```(?P<lang>\w*)\n(?P<body>.*?)\n```", re.S)


def blocks(doc: str) -> list[tuple[str, str, str]]:
    """``(mark, language, body)`` of every fenced block, in order."""
    text = (ROOT / doc).read_text()
    return [(m["mark"] or "", m["lang"], m["body"]) for m in BLOCK.finditer(text)]


@pytest.mark.parametrize("doc", DOCS)
def test_the_docs_copies_of_the_example_files_are_the_files(doc):
    copies = [(mark, body) for mark, _, body in blocks(doc) if mark.startswith("the file ")]
    assert copies
    for mark, body in copies:
        path = ROOT / mark.removeprefix("the file ")
        assert body + "\n" == path.read_text(), path


def _expected(line: str) -> re.Pattern:
    return re.compile(".*".join(re.escape(p) for p in line.split("...")))


def _console(body: str, env: dict, runs: Path) -> None:
    commands: list[tuple[str, list[str]]] = []
    for line in body.splitlines():
        if line.startswith("$ "):
            commands.append((line[2:], []))
        else:
            commands[-1][1].append(line)
    for command, shown in commands:
        res = subprocess.run(["bash", "-c", command.replace("runs/", f"{runs}/")], cwd=ROOT,
                             env=env, capture_output=True, text=True, timeout=600)
        code = next((int(s[6:-1]) for s in shown if re.fullmatch(r"\[exit \d+\]", s)), 0)
        out = (res.stdout + res.stderr).splitlines()
        assert res.returncode == code, (command, res.stdout, res.stderr)
        assert "Traceback" not in res.stderr, (command, res.stderr)
        for s in shown:
            if s.startswith("[exit "):
                continue
            pattern = _expected(s)
            assert any(pattern.fullmatch(o) for o in out), (command, s, out)


@pytest.mark.parametrize("doc", DOCS)
def test_the_walk_through_runs_as_written(doc, example_fmus, tmp_path):
    runs = tmp_path / "runs"
    runs.mkdir()
    env = uwcosim_env(PYTHONPATH=str(EXAMPLE))
    ran = 0
    for mark, lang, body in blocks(doc):
        if mark.startswith(("the file ", "not run by the tests")):
            continue
        if lang == "console":
            _console(body, env, runs)
        elif lang == "sh":
            res = subprocess.run(["bash", "-e", "-c", body.replace("runs/", f"{runs}/")],
                                 cwd=ROOT, env=env, capture_output=True, text=True,
                                 timeout=900)
            assert res.returncode == 0, (body, res.stdout[-3000:], res.stderr[-3000:])
        elif lang == "python":
            res = subprocess.run([sys.executable, "-c", body.replace("runs/", f"{runs}/")],
                                 cwd=ROOT, env=env, capture_output=True, text=True,
                                 timeout=600)
            assert res.returncode == 0, (body, res.stderr[-3000:])
        else:
            continue
        ran += 1
    assert ran >= 4
