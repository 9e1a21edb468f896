"""The shell command that reproduces a run: copy-pasteable, every argument shell-quoted.

The scenario is named by its absolute path (``summary.json`` ``scenario_file``; older runs only
logged the file name), the seed is the seed the run used, each ``--set`` override is quoted as
one shell word (TOML values with spaces, quotes or braces survive), and the output goes to a
sibling folder so the original run stays as it is. Paths given with ``--set`` were made absolute
when the run was loaded, so the command does not depend on the current folder.
"""

from __future__ import annotations

import shlex
from pathlib import Path


def reproduce_command(summary: dict, meta: dict, run_dir: Path | None = None) -> str:
    """``uwcosim run SCENARIO --seed N [--set KEY=VALUE ...] [--out DIR]``, shell-quoted."""
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
    return shlex.join(words)
