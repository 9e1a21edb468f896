"""The scenario layer: scenario files (TOML, or an SSP) loaded, validated and converted.

The schema (``schema``, reusing the system layer's records), ``--set`` overrides
(``overrides``), loading (``load``; an SSP as the truth side: ``ssp``), validation that
reports every problem (``validate``), the JSON Schema (``json_schema``) and the conversion to
the master's input (``system.to_system``); ``[replay]`` and its file (``replay``), controls read
from files (``control_files``) and ``[geo]``, the geographic frame (``geo``).
"""

from uwcosim.scenario.load import load_scenario
from uwcosim.scenario.overrides import parse_overrides
from uwcosim.scenario.schema import Scenario
from uwcosim.scenario.system import to_system

__all__ = ["Scenario", "load_scenario", "parse_overrides", "to_system"]
