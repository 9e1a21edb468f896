"""Ship the example scenarios, the golden baselines and the docs inside the package in wheels.

Everything else is in pyproject.toml. The files stay where the checkout has them
(``scenarios/``, ``tests/baselines/``, ``docs/`` and ``README.md``); a built wheel carries copies
under ``uwcosim/_data/`` (``scenarios``, ``baselines``, ``docs``), found by
:mod:`uwcosim.core.paths` when no checkout is around. Editable installs skip the copies.
"""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent


class BuildWithData(build_py):
    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return
        data = Path(self.build_lib) / "uwcosim" / "_data"
        for src, dst, patterns in (
                (HERE / "scenarios", data / "scenarios", ("*.toml",)),
                (HERE / "tests" / "baselines", data / "baselines", ("*.parquet",)),
                (HERE / "docs", data / "docs", ("*.md", "*.png", "*.svg", "*.csv"))):
            for path in sorted(p for pattern in patterns for p in src.rglob(pattern)):
                target = dst / path.relative_to(src)
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(path, target)
        shutil.copyfile(HERE / "README.md", data / "docs" / "README.md")


setup(cmdclass={"build_py": BuildWithData})
