"""A full disk (issue 24, item 10): one line, a non-zero exit, ``summary.json`` says
``failed`` when it can be written, and nothing says ok that is not.

The run writes into a small tmpfs (``mount -t tmpfs -o size=N``) when this process may mount
one (root with CAP_SYS_ADMIN, as in the project's CI container); otherwise the map case runs
under ``RLIMIT_FSIZE`` (a per-file size limit: ``EFBIG`` instead of ``ENOSPC``) and the
others are skipped. Real processes: ``python -m uwcosim run``.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import without_progress

ROOT = Path(__file__).resolve().parents[1]
SCEN = ROOT / "scenarios" / "tan_terrain.toml"
EKF = 'estimators={ekf={type="ekf"}}'

# (id, tmpfs size, --set items, what the one line names)
CASES = [
    ("map", "200k", [EKF], "cannot write the map file; the run did not start"),
    ("log", "2m", [], "cannot write the log"),
    ("figures", "2100k", [EKF], "cannot write the report and figures (the run itself "
                                "finished)"),
]


def _mount(folder: Path, size: str) -> bool:
    folder.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)],
                       capture_output=True)
    return r.returncode == 0


def _run(out: Path, items: list[str], fsize: int | None = None) -> subprocess.CompletedProcess:
    def limit() -> None:
        if fsize is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

    args = [sys.executable, "-m", "uwcosim", "run", str(SCEN), "--out", str(out), "--set",
            "run.duration=20", *(a for i in items for a in ("--set", i))]
    return subprocess.run(args, capture_output=True, text=True, preexec_fn=limit, timeout=300)


def _check(r: subprocess.CompletedProcess, out: Path, expected: str) -> None:
    lines = without_progress(r.stderr).strip().splitlines()
    assert r.returncode == 1, r.stderr
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert expected in lines[0] and str(out) in lines[0], lines[0]
    assert not list(out.glob("*.tmp")), list(out.iterdir())
    for name in ("summary.json", "simulation.json"):
        if (out / name).exists():
            assert json.loads((out / name).read_text())["status"] == "failed"
    if (out / "densities.npz").exists():
        assert (out / "densities.npz").stat().st_size > 0


@pytest.mark.parametrize(("size", "items", "expected"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_a_full_disk_is_one_line_and_no_false_ok(tmp_path, size, items, expected):
    mnt = tmp_path / "disk"
    if not _mount(mnt, size):
        if size != "200k":
            pytest.skip("cannot mount a tmpfs here (the map case runs under RLIMIT_FSIZE)")
        out = tmp_path / "run"
        r = _run(out, items, fsize=200_000)
        _check(r, out, expected)
        return
    try:
        out = mnt / "run"
        r = _run(out, items)
        _check(r, out, expected)
        if size == "200k":  # the map did not fit: the failed summary did
            assert json.loads((out / "summary.json").read_text())["status"] == "failed"
    finally:
        subprocess.run(["umount", str(mnt)], capture_output=True)
