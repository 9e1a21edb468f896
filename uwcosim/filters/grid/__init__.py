"""What the grid filters share: PFM-PSI (:mod:`uwcosim.filters.projection`) and the point mass
(:mod:`uwcosim.filters.point_mass`) represent the density of a few *gridded* states on a
spectral basis or a grid, and run a Kalman filter for the others.

- ``partition``: the split of the state into gridded and Kalman states from the model's CasADi
  structure, the Fokker-Planck coefficient fields of the gridded block, the split of the
  available measurement rows (numpy and compiled forms);
- ``conditional``: the conditional Kalman block (numpy and compiled forms) and the assembly of
  the filter's ``(x, P)``; ``conditional_kernels``: its compiled kernels and their bundles
  (``KalmanBlock``, ``ModelStep``);
- ``likelihood``: the likelihood of the gridded measurement rows on a tensor grid, the
  separable terrain spline (``TerrainGrid``) and its compiled form (``terrain_depth``);
- ``estimator``: the frame of both filters (``GridFilter``: the partition, the Kalman block and
  the likelihood built once, ``predict`` and ``update`` around the filter's own density and
  steps);
- ``moments``: mean and covariance of a density on a tensor grid (numpy and compiled forms).

The compiled loops for the small matrices of their steps are :mod:`uwcosim.filters.small_linalg`
(the Kalman family's compiled steps use them too).
"""
