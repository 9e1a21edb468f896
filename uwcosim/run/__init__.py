"""The run layer: one scenario, one seed, into a run directory.

The simulate stage (``simulate``: master, estimator bank, log), the estimator bank
(``bank``) with its divergence checks (``divergence``, ``scan``), the log recorder
(``recorder``), the density snapshots (``density``), the filters' model of a scenario
(``factory``) and ``uwcosim check``'s FMU and filter levels (``preflight``). See
``docs/architecture.md``.
"""
