"""The point-mass (grid) filter (estimator ``point_mass``), by concept.

- ``grid``: the density on a regular grid re-centred on the support every step;
- ``prediction``: the density carried to the new grid (spline shift and Gaussian blur by FFT,
  or the Chapman-Kolmogorov sum); ``fft``: its FFT work arrays and frequency tables;
- ``bayes``: the Bayes update on the grid;
- ``filter``: :class:`~uwcosim.filters.point_mass.filter.PointMassFilter` itself;
- the compiled forms (two gridded states, Numba) with their kernels: ``prediction_kernels``,
  ``bayes_kernels``.

The state partition, the conditional Kalman block, the grid likelihood and the filter's frame
(``GridFilter``: ``predict``, ``update``) are shared with PFM-PSI in :mod:`uwcosim.filters.grid`.
"""
