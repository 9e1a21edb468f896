"""Run logs: Parquet files with the run's metadata, written as the run goes."""

from uwcosim.runlog.parquet import RunLogger, read_log, read_units, recover_log

__all__ = ["RunLogger", "read_log", "read_units", "recover_log"]
