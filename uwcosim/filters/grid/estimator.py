"""The grid filters' step: a density of the gridded states and the conditional Kalman filter of
the others, advanced by a prediction and a Bayes update.

PFM-PSI (a series on a box) and the point mass (values on a grid) are the same filter around
different representations of the gridded density ``p(x_p | z)``: the state is split by
:class:`~uwcosim.filters.grid.partition.Partition`, the other states ``x_k`` (the TAN model's
velocities) are carried by the Kalman filter conditional on the gridded ones
(:mod:`uwcosim.filters.grid.conditional`), and the likelihood of the gridded measurement rows is
:class:`~uwcosim.filters.grid.likelihood.GridLikelihood`. :class:`GridFilter` holds that
common frame:

- at construction the partition, the Kalman block and the likelihood, and whether the steps
  run their compiled forms (:attr:`GridFilter.fast`: two gridded states, kernels on, and the
  settings the filter's compiled forms cover, :meth:`GridFilter.compiles`);
- :meth:`GridFilter.predict`: the prediction step the model needs (chosen once,
  :meth:`GridFilter.begin`) of the density and the Kalman block;
- :meth:`GridFilter.update`: the Kalman block's update with its rows, the Bayes product of
  the density with the gridded rows, and the diagnostics of the representation (its size and
  its box, :meth:`GridFilter.representation`).

Each step returns the assembled ``(x, P, finite)`` of the filter
(:meth:`~uwcosim.filters.grid.conditional.ConditionalKalman.assemble`); a non-finite one raises
:class:`~uwcosim.core.errors.FilterDivergence`. A filter of the family builds its density and
its two steps, then calls :meth:`GridFilter.begin`.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from uwcosim.core.errors import FilterDivergence
from uwcosim.core.jit import ENABLED
from uwcosim.filters.base import Estimator
from uwcosim.filters.grid.conditional import CompiledConditionalKalman, ConditionalKalman
from uwcosim.filters.grid.likelihood import GridLikelihood
from uwcosim.filters.grid.partition import Partition, symbolic
from uwcosim.filters.settings import FilterSettings

#: a prediction step: ``(density, x, u, dt, diagnostics) -> (x, P, finite)``
PredictStep = Callable[[Any, np.ndarray, np.ndarray, float, dict], tuple]


class GridFilter(Estimator):
    """A density of the gridded states with the conditional Kalman filter of the others.

    Subclasses set :attr:`density`, :attr:`prediction` (its step passed to :meth:`begin`) and
    :attr:`bayes` (``update(density, x, z, rows_k, rows_g, diagnostics)``), and say what the
    representation is (:attr:`size_key`, :meth:`representation`). Their ``Settings`` have
    ``states``, ``measurements``, ``long_run`` and ``student_t_nu``.
    """

    #: False: the numpy forms of the steps even where the compiled ones apply (the reference
    #: they are tested against)
    use_kernels: ClassVar[bool] = True
    #: the diagnostic that reports the size of the representation after an update
    size_key: ClassVar[str] = "n_points"

    def __init__(self, model, x0, P0, **settings) -> None:
        model = symbolic(model)
        super().__init__(model, x0, P0, **settings)
        s = self.settings
        kernels = self.use_kernels and ENABLED
        #: the split of the state and of the measurement rows
        self.part = Partition(model, s.states, s.measurements, compiled=kernels)
        #: the steps run their compiled forms (two gridded states, the settings they cover)
        self.fast = bool(kernels and len(self.part.p) == 2 and self.compiles(s))
        kalman = CompiledConditionalKalman if self.fast else ConditionalKalman
        #: the conditional Kalman filter of the other states
        self.kalman = kalman(model, self.part, self.x, self.P, s.long_run)
        #: the likelihood of the gridded measurement rows
        self.likelihood = GridLikelihood(model, self.part, s.student_t_nu)
        self._keys = [(f"interval_lo_{n}", f"interval_hi_{n}") for n in self.part.names]
        self._predict: PredictStep | None = None
        self._after_update = False

    @classmethod
    def compiles(cls, settings: FilterSettings) -> bool:
        """The filter's compiled steps cover these settings (with two gridded states)."""
        return True

    def gridded_prior(self) -> tuple[np.ndarray, np.ndarray]:
        """The mean and covariance of the gridded states in ``x0``, ``P0``; ValueError unless
        every gridded state has a positive variance."""
        p = self.part.p
        mean, cov = self.x[p], self.P[np.ix_(p, p)]
        if np.any(np.diag(cov) <= 0):
            raise ValueError("P0 must have a positive variance for every gridded state")
        return mean, cov

    def begin(self, predict: PredictStep, mean: np.ndarray, cov: np.ndarray) -> None:
        """Start the filter once its density and steps are built: ``predict`` is the
        prediction step the model needs (chosen once), ``(x, P)`` are assembled from the
        gridded block's ``mean``, ``cov`` and the Kalman block."""
        self._predict = predict
        self._accept(*self.kalman.assemble(mean, cov))

    def _accept(self, x: np.ndarray, P: np.ndarray, finite: bool) -> None:
        if not finite:
            raise FilterDivergence(f"{self.kind}: non-finite estimate")
        self.x, self.P = x, P

    # ------------------------------------------------------------------------------------------
    def predict(self, u, dt: float) -> None:
        self.diagnostics = {}
        self._after_update = False
        u = np.asarray(u, dtype=float).reshape(-1)
        self._accept(*self._predict(self.density, self.x, u, dt, self.diagnostics))

    def update(self, z, mask=None) -> None:
        if self._after_update:  # fresh diagnostics, unless a prediction just wrote them
            self.diagnostics = {}
        self._after_update = True
        z, rows_k, rows_g = self.part.split_rows(z, mask)
        self._accept(*self.bayes.update(self.density, self.x, z, rows_k, rows_g,
                                        self.diagnostics))
        size, lo, hi = self.representation()
        d = self.diagnostics
        d[self.size_key] = size
        for (klo, khi), a, b in zip(self._keys, lo, hi, strict=True):
            d[klo] = a
            d[khi] = b

    @abstractmethod
    def representation(self) -> tuple[float, list[float], list[float]]:
        """The size of the density's representation (:attr:`size_key`) and its box:
        ``(size, lo, hi)`` with one bound per gridded state."""

    @property
    def gridded_states(self) -> list[str]:
        return self.part.names
