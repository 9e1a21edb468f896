"""The core layer: what every other layer may use, importing nothing of uwcosim but itself.

The error hierarchy (``errors``), name registries (``registry``), TOML reading (``tomlfile``),
where files live (``paths``), the cubic B-spline (``bspline``), the RK4 step
(``integrators``), the master's seeded random streams (``rng``), the Numba binder of the
compiled kernels (``jit``) and their fixed-order reductions (``reductions``), child processes
(``process``), the run's scratch folders (``scratch``) and the run's signal guard
(``runguard``). See ``docs/architecture.md``.
"""
