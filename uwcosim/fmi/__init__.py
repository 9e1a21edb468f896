"""The FMI layer: one FMU as an object, over fmpy (imports only :mod:`uwcosim.core`).

The archive and its checks (``archive``), the FMI types (``vartypes``), variable maps of
third-party FMUs (``varmap``), the adapter of one FMU (``adapter``: co-simulation and model
exchange, FMI 2.0 and 3.0), its typed get/set buffers (``binding``), the model-exchange
integrators (``solvers``) and the worker-process proxy of an FMU with a time limit
(``proxy``). See ``docs/architecture.md``.
"""
