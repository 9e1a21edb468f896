"""A String-typed test FMU exported with pythonfmu (FMI 2.0 co-simulation).

``s_out`` is ``prefix + s_in`` in upper case, ``n`` its length (Integer) and ``t_str`` the
FMU's time as text, so the master's String inputs, outputs, connections and log columns can be
checked (the C test FMUs have no String input or output).
"""

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer, String


class Shout(Fmi2Slave):
    author = "uwcosim tests"
    description = "String in, String out"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.prefix = ""
        self.s_in = "abc"
        self.s_out = ""
        self.n = 0
        self.t_str = ""
        self.register_variable(String("prefix", causality=Fmi2Causality.parameter,
                                      variability=Fmi2Variability.fixed))
        self.register_variable(String("s_in", causality=Fmi2Causality.input,
                                      variability=Fmi2Variability.discrete))
        for var in (String("s_out", causality=Fmi2Causality.output,
                           variability=Fmi2Variability.discrete, initial=Fmi2Initial.calculated),
                    Integer("n", causality=Fmi2Causality.output,
                            variability=Fmi2Variability.discrete,
                            initial=Fmi2Initial.calculated),
                    String("t_str", causality=Fmi2Causality.output,
                           variability=Fmi2Variability.discrete,
                           initial=Fmi2Initial.calculated)):
            self.register_variable(var)

    def _calc(self, t):
        self.s_out = (self.prefix + self.s_in).upper()
        self.n = len(self.s_out)
        self.t_str = f"t={t:.2f}"

    def exit_initialization_mode(self):
        self._calc(0.0)

    def do_step(self, current_time, step_size):
        self._calc(current_time + step_size)
        return True
