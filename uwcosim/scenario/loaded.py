"""A scenario as loaded: the validated spec with its source text, file, overrides and hash."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from uwcosim.scenario.schema import Scenario


@dataclass(frozen=True)
class LoadedScenario:
    """A validated scenario with its source text, the file it came from and its hash."""

    spec: Scenario
    path: Path
    text: str
    overrides: tuple[str, ...]
    #: the SSP of ``[system] ssp`` or of an ``.ssp`` run
    #: (:class:`uwcosim.scenario.ssp.convert.SSPArchive`)
    ssp: Any = None

    @property
    def base_dir(self) -> Path:
        return self.path.parent

    def resolve(self, relpath: str) -> Path:
        p = Path(relpath)
        return p if p.is_absolute() else (self.base_dir / p).resolve()

    @property
    def sha256(self) -> str:
        h = hashlib.sha256(self.text.encode())
        for o in self.overrides:
            h.update(b"\0" + o.encode())
        if self.ssp is not None:
            h.update(b"\0ssp:" + self.ssp.sha256.encode())
        return h.hexdigest()
