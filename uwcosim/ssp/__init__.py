"""SSP export (a tool): a scenario's truth side written as an ``.ssp`` (``export``). Reading an
SSP as the truth side of a scenario is part of the scenario layer
(:mod:`uwcosim.scenario.ssp`); see ``docs/ssp.md``."""
