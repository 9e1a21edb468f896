"""Measurements of a run, from one owner: the :class:`SensorBank`.

A sensor (``[sensors.NAME]``) is a group of FMU outputs measured together. The bank does for
every sensor, with the master's seeded streams (:func:`~uwcosim.core.rng.stream`):

- **sampling**: a sample every ``period`` steps, the first at step ``period`` (never at ``t0``);
- **loss**: a seeded mask per sensor (stream ``loss:NAME``; Bernoulli or Gilbert-Elliott, seed
  001 eq. 2), so a sample is *received* when it is sampled and not lost;
- **noise** (stream ``sensor-noise:NAME``, standard deviations ``sigma``): into the FMU's noise
  inputs (``noise_inputs``; loaded on the bus before the step that uses them, like the master's
  other sources), or, for a sensor without noise inputs, added to its outputs;
- **validity**: a sensor with a ``valid`` output (a DVL's bottom lock) is received only when
  that output is nonzero at the step;
- **assembly**: ``z`` (the measured sensors' outputs in order, plus additive noise, NaN where
  not received) and the ``received`` mask, one :class:`Measurement` per step, computed once and
  read by the estimators and the logger alike.

The measured sensors (the components of ``z``) are ``System.measured`` (a scenario's
``[model] sensors``; by default every sensor). Samples are drawn in chunks as the run goes
(:class:`~uwcosim.master.sources.ChunkedTable`), in the same order as one draw for the run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uwcosim.core.rng import stream
from uwcosim.master.sources import ChunkedTable, gaussian_drawer, loss_drawer


@dataclass(frozen=True)
class Measurement:
    """What the sensors delivered at step ``k`` (time ``t``)."""

    k: int
    t: float
    #: measured values (noise included), NaN where not received
    z: np.ndarray
    #: bool, per component of ``z``: sampled and not lost
    received: np.ndarray


class SensorBank:
    """Sampling, loss, noise and assembly of the measurements of a system's sensors.

    ``output_slots``: bus slots of each sensor's outputs; ``input_slots``: bus slots of each
    sensor's noise inputs (empty when it has none); ``measured``: the sensors forming ``z``, in
    order; ``n``: grid points of the run (steps + 1).
    """

    def __init__(self, sensors: dict, output_slots: dict[str, np.ndarray],
                 input_slots: dict[str, list[int]], measured: list[str], seed: int,
                 n: int, valid_slots: dict[str, int] | None = None) -> None:
        self.measured = list(measured)
        self.names = [o for s in self.measured for o in sensors[s].outputs]
        #: the sensor of each component of z
        self.sensor_of = [s for s in self.measured for _ in sensors[s].outputs]
        self.slots = np.array([i for s in self.measured for i in output_slots[s]], dtype=np.intp)
        # noise into FMU inputs: every sensor that has noise inputs, measured or not
        noisy = [s for s, spec in sensors.items() if spec.noise_inputs]
        self.input_slots = np.array([i for s in noisy for i in input_slots[s]], dtype=np.intp)
        self.inputs = ChunkedTable(n, [
            lambda s=s: gaussian_drawer(stream(seed, f"sensor-noise:{s}"), sensors[s].sigma)
            for s in noisy], self.input_slots.size)
        # additive noise of the measured sensors without noise inputs (zeros for the others)
        makers = []
        for s in self.measured:
            spec = sensors[s]
            if spec.sigma and not spec.noise_inputs:
                makers.append(lambda s=s: gaussian_drawer(stream(seed, f"sensor-noise:{s}"),
                                                          sensors[s].sigma))
            else:
                makers.append(lambda w=len(spec.outputs): lambda k0, m: np.zeros((m, w)))
        self.additive = ChunkedTable(n, makers, self.slots.size)
        # received: sampled and not lost, one column per measured sensor
        self.masks = ChunkedTable(n, [self._mask_maker(sensors[s], s, seed, n)
                                      for s in self.measured], len(self.measured), dtype=bool)
        index = {s: i for i, s in enumerate(self.measured)}
        self._column = np.array([index[s] for s in self.sensor_of], dtype=np.intp)
        self._last: Measurement | None = None
        # validity outputs: the bus slot per component of z (-1: always valid)
        valid_slots = valid_slots or {}
        self._valid = np.array([valid_slots.get(s, -1) for s in self.sensor_of], dtype=np.intp) \
            if any(s in valid_slots for s in self.measured) else None

    @staticmethod
    def _mask_maker(spec, name: str, seed: int, n: int):
        def maker():
            lost = loss_drawer(stream(seed, f"loss:{name}"), n, spec.loss)

            def draw(k0: int, m: int) -> np.ndarray:
                k = np.arange(k0, k0 + m)
                return ((k % spec.period == 0) & (k > 0)) & lost(k0, m)
            return draw
        return maker

    def load_inputs(self, k: int, bus: np.ndarray) -> None:
        """Put the FMU noise inputs of step ``k -> k+1`` on the bus."""
        if self.input_slots.size:
            bus[self.input_slots] = self.inputs.row(k)

    def received(self, k: int) -> np.ndarray:
        """Per component of ``z``: sampled and not lost at step ``k`` (steps in order)."""
        return self.masks.row(k)[self._column]

    def measure(self, k: int, t: float, bus: np.ndarray) -> Measurement:
        """The measurement at step ``k`` from the bus (computed once per step)."""
        last = self._last
        if last is not None and last.k == k:
            return last
        rec = self.received(k)
        if self._valid is not None:  # e.g. no bottom lock: not received
            rec = rec & ((self._valid < 0) | (bus[self._valid] != 0.0))
        z = np.where(rec, bus[self.slots] + self.additive.row(k), np.nan)
        self._last = Measurement(k, t, z, rec)
        return self._last
