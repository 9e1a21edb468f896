"""Regression tests on logged outputs: compare a run's log with a baseline inside tolerance
tubes (:mod:`uwcosim.regress.compare`), keep golden baselines of the shipped scenarios
(:mod:`uwcosim.regress.baselines`) and check one in a line of pytest
(:mod:`uwcosim.regress.pytest_helper`)."""

from uwcosim.regress.compare import (
    DEFAULT_ATOL,
    DEFAULT_RTOL,
    DEFAULT_TTOL,
    RegressionInputError,
    RegressionReport,
    compare_logs,
)

__all__ = ["DEFAULT_ATOL", "DEFAULT_RTOL", "DEFAULT_TTOL", "RegressionInputError",
           "RegressionReport", "compare_logs"]
