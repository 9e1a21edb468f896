"""A third-party vehicle FMU for the tests, exported with pythonfmu (FMI 2.0 co-simulation).

The kinematics of Chen et al. (eq. 54) in other conventions than uwcosim's: positions in
north-east order, heading in degrees clockwise from north, surge/sway speeds in knots with sway
positive to starboard, start values as parameters, and no declared units (pythonfmu declares
none: the variable map gives them). No process-noise inputs.
"""

import math

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Real

KNOT = 1852.0 / 3600.0  # m/s


class NorthEastVehicle(Fmi2Slave):
    author = "uwcosim tests"
    description = "Planar AUV kinematics, north-east, compass heading (deg), knots"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.north_0 = 0.0
        self.east_0 = 0.0
        self.surge_0 = 0.0
        self.sway_0 = 0.0
        self.north = 0.0
        self.east = 0.0
        self.surge = 0.0
        self.sway = 0.0
        self.heading = 0.0
        self.accel = 0.0
        self.heading_out = 0.0
        for name in ("north_0", "east_0", "surge_0", "sway_0"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed))
        for name in ("heading", "accel"):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in ("north", "east", "surge", "sway", "heading_out"):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        initial=Fmi2Initial.calculated))

    def exit_initialization_mode(self):
        self.north, self.east = self.north_0, self.east_0
        self.surge, self.sway = self.surge_0, self.sway_0
        self.heading_out = self.heading

    def _rates(self, s):
        north, east, u, v = s
        chi = math.radians(self.heading)
        c, d = math.cos(chi), math.sin(chi)
        a = self.accel
        return (KNOT * (u * c - v * d), KNOT * (u * d + v * c), a * d / KNOT, -a * c / KNOT)

    def do_step(self, current_time, step_size):
        s = (self.north, self.east, self.surge, self.sway)
        h = step_size
        k1 = self._rates(s)
        k2 = self._rates([x + h / 2 * k for x, k in zip(s, k1)])
        k3 = self._rates([x + h / 2 * k for x, k in zip(s, k2)])
        k4 = self._rates([x + h * k for x, k in zip(s, k3)])
        s = [x + h / 6 * (p + 2 * q + 2 * r + w) for x, p, q, r, w in zip(s, k1, k2, k3, k4)]
        self.north, self.east, self.surge, self.sway = s
        self.heading_out = self.heading
        return True
