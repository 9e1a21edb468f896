"""Grid filters: the partitioned point-mass (``point_mass``) and projection (``pfm_psi``) filters.

Both represent the density of a few *gridded* states on a grid or a spectral basis and run a
Kalman filter for the others. Everything only they use lives here: the state partition and the
model analysis (``partition``), the measurement likelihood on a tensor grid (``likelihood``), the
spectral machinery of the projection filter (``spectral``) and the compiled kernels
(``projection_kernels``, ``projection_kalman``, ``projection_predict``,
``point_mass_kernels``).
"""
