"""The run layer: one scenario, one seed, into a run directory.

The simulate stage (``simulate``: master, estimator bank, log), the estimator bank
(``bank``) with its divergence checks (``divergence``, ``scan``), the log recorder
(``recorder``; a georeferenced log's latitude/longitude: ``geocolumns``), the density
snapshots (``density``), the filters' model of a scenario (``factory``), the replay of a
recorded file in the master's place (``replay``), ``uwcosim check``'s FMU, replay and
filter levels (``preflight``) and the run directory of a run whose process an FMU ended
(``aftermath``). See ``docs/architecture.md``.
"""
