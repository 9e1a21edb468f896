"""PFM-PSI, the projection filter of seed 000 (estimator ``pfm_psi``), by concept.

- ``series``: the basis on the projection symmetric interval and its quadrature (eqs. 33-41),
  the mass and normalization (eqs. 39-40, 44, 48), the re-projection onto another box, the
  exact moments of the series (eqs. 50-51); the numpy form of the operations every step uses;
- ``prediction``: the Galerkin matrix of the Fokker-Planck operator and the prior
  ``exp(A dt) m`` (eqs. 15, 23, 41-43);
- ``bayes``: the Bayes update (eqs. 45-48), the posterior moments (eqs. 50-51), the positivity
  repairs, the representation-error inflation, the refinement and the gate;
- ``filter``: :class:`~uwcosim.filters.projection.filter.ProjectionFilter` itself;
- the compiled forms (two gridded states, Numba) of each concept, with their kernels:
  ``series_kernels`` (series <-> grid transforms, box, normalization, re-projection with the
  Gaussian decay), ``prediction_kernels`` (the fused prediction), ``bayes_kernels`` (the
  product, its moments and the fused updates).

The state partition, the conditional Kalman block of the velocities, the grid likelihood and
the filter's frame (``GridFilter``: ``predict``, ``update``) are shared with the point mass in
:mod:`uwcosim.filters.grid`.
"""
