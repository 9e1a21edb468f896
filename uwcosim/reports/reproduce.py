"""The shell command that reproduces a run: copy-pasteable, every argument shell-quoted.

The scenario is named by its absolute path (``summary.json`` ``scenario_file``; older runs only
logged the file name), the seed is the seed the run used, each ``--set`` override is quoted as
one shell word (TOML values with spaces, quotes or braces survive), and the output goes to a
sibling folder so the original run stays as it is. Paths given with ``--set`` were made absolute
when the run was loaded, so the command does not depend on the current folder.

A user's filter or model imported by path from the current folder of the run (not from the
scenario's folder, which the run puts on ``sys.path`` wherever it starts; the log's metadata
``user_code`` says where each module was found) makes the command start with ``cd`` into that
folder, so that the same module is imported again.
"""

from __future__ import annotations

import shlex
from pathlib import Path


def user_code_folder(summary: dict, meta: dict) -> str | None:
    """The folder a user's module of the run was imported from when it is not the
    scenario's folder (the run's current folder), else None."""
    scenario = summary.get("scenario_file")
    here = str(Path(scenario).resolve().parent) if scenario else None
    code = meta.get("user_code") or {}
    origins = [*(code.get("estimators") or {}).values()] + \
        ([code["model"]] if code.get("model") else [])
    return next((o["found_in"] for o in origins
                 if o.get("found_in") and o["found_in"] != here), None)


def user_code_lines(meta: dict) -> list[str]:
    """One line per user's filter or model of the run: type, module file, sha256, version."""
    code = meta.get("user_code") or {}
    items = [(f"estimator {n!r}", o) for n, o in (code.get("estimators") or {}).items()]
    if code.get("model"):
        items.append(("model", code["model"]))
    out = []
    for what, o in items:
        version = f", {o['package']} {o.get('version', '')}".rstrip() if o.get("package") \
            else (f", version {o['version']}" if o.get("version") else "")
        out.append(f"{what}: {o.get('type')} = {o.get('target')} ({o.get('source')}; "
                   f"{o.get('module_file', '?')}, sha256 {str(o.get('module_sha256'))[:16]}"
                   f"{version})")
    return out


def reproduce_command(summary: dict, meta: dict, run_dir: Path | None = None) -> str:
    """``uwcosim run SCENARIO --seed N [--set KEY=VALUE ...] [--out DIR]``, shell-quoted
    (preceded by ``cd DIR &&`` when a user's module came from the run's current folder, and
    by ``UWCOSIM_NUMBA=0`` when the run's kernels were the numpy forms: metadata ``kernels``;
    the two differ in the last bits, about 1e-11)."""
    scenario = summary.get("scenario_file") or meta.get("scenario_path") or "SCENARIO.toml"
    seed = summary.get("seed", meta.get("seed"))
    words = ["uwcosim", "run", str(scenario)]
    if seed is not None:
        words += ["--seed", str(int(seed))]
    for o in meta.get("overrides", []):
        words += ["--set", str(o)]
    if run_dir is not None:
        run_dir = Path(run_dir).resolve()
        words += ["--out", str(run_dir.with_name(run_dir.name + "-reproduced"))]
    folder = user_code_folder(summary, meta)
    prefix = f"cd {shlex.quote(folder)} && " if folder else ""
    if meta.get("kernels") == "numpy":
        prefix += "UWCOSIM_NUMBA=0 "
    return prefix + shlex.join(words)
