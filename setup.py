"""Ship the example scenarios inside the package (``uwcosim/_data/scenarios``) in wheels.

Everything else is in pyproject.toml. The scenarios stay in ``scenarios/`` of the checkout (the
tests, baselines and docs use them there); a built wheel carries a copy, found by
:func:`uwcosim.core.paths.scenarios_dir` when no checkout is around. Editable installs skip the copy.
"""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent


class BuildWithScenarios(build_py):
    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return
        src = HERE / "scenarios"
        dst = Path(self.build_lib) / "uwcosim" / "_data" / "scenarios"
        for path in sorted(src.rglob("*.toml")):
            target = dst / path.relative_to(src)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, target)


setup(cmdclass={"build_py": BuildWithScenarios})
