"""Scenario files (TOML): schema, loading, overrides and validation."""

from uwcosim.scenario.load import load_scenario, parse_overrides
from uwcosim.scenario.schema import Scenario

__all__ = ["Scenario", "load_scenario", "parse_overrides"]
