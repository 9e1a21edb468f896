"""An EKF with an innovation gate: ``type = "current_nav.gated_ekf:GatedEKF"`` in
``[estimators.NAME]`` (or ``type = "gated_ekf"`` once this package is installed: its entry
point).

A measurement component whose innovation exceeds ``gate`` standard deviations of its predicted
distribution (``|z_i - h_i(x)| > gate sqrt(S_ii)``, ``S = H P H' + R``) is left out of the
update: a multipath range, several tens of metres too long, does not pull the estimate.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field, StrictFloat

from uwcosim.filters import FilterSettings, Measurements, measurements_field
from uwcosim.filters.kalman import ExtendedKalmanFilter


class GatedEKF(ExtendedKalmanFilter):
    """EKF whose update leaves out the components outside an innovation gate."""

    class Settings(FilterSettings):
        gate: StrictFloat = Field(3.0, gt=0, description="innovation gate, in standard "
                                  "deviations of the predicted measurement")
        gated: Measurements = measurements_field("measurement components the gate applies "
                                                 "to (default: all)")
        measurements: Measurements = measurements_field()

    def __init__(self, model, x0, P0, **settings) -> None:
        super().__init__(model, x0, P0, **settings)
        names = model.measurement_names
        gated = self.settings.gated
        unknown = [g for g in gated or () if g not in names]
        if unknown:
            raise ValueError(f"gated: unknown measurements {unknown} (valid: {', '.join(names)})")
        self._gated = np.array([gated is None or n in gated for n in names])
        self._r = np.diag(model.R).copy()
        #: components left out so far
        self.rejected = 0

    def update(self, z, mask=None) -> None:
        n_out = 0
        if z is not None:
            z = np.asarray(z, dtype=float)
            ok = np.isfinite(z) if mask is None else np.asarray(mask, bool) & np.isfinite(z)
            H = self.model.H(self.x)
            s = np.einsum("ij,jk,ik->i", H, self.P, H) + self._r  # diag(H P H' + R)
            y = np.where(ok, z - self.model.h(self.x), 0.0)
            out = ok & self._gated & (np.abs(y) > self.settings.gate * np.sqrt(s))
            n_out = int(out.sum())
            mask = ok & ~out
        super().update(z, mask)
        self.rejected += n_out
        self.diagnostics["gated"] = float(n_out)
