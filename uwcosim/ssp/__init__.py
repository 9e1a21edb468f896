"""SSP (System Structure and Parameterization 1.0): read an ``.ssp`` as the truth side of a
scenario, and export a scenario's truth side as an ``.ssp`` (see ``docs/ssp.md``)."""

from uwcosim.ssp.read import FlatComponent, FlatConnection, FlatSystem, read_ssp

__all__ = ["FlatComponent", "FlatConnection", "FlatSystem", "read_ssp"]
