"""The FMI layer: one FMU as an object, over fmpy (imports only :mod:`uwcosim.core`).

- ``archive``: the archive and its checks (readable zip, model description, this platform's
  binary), with the build hint for a missing FMU of the project's own;
- ``vartypes``: the FMI 2.0 / 3.0 types, value checks and conversions;
- ``structure``: the model structure (which outputs depend directly on which inputs, whether
  it gives their directional derivatives);
- ``features``: what an FMU needs that the master does not do (scheduled execution only,
  FMI 3 clocks);
- ``varmap``: variable maps of third-party FMUs (roles, units, conventions);
- ``binding``: value references and typed get/set buffers of a group of variables (FMI 3
  arrays, exact 64-bit integers);
- ``instance``: one instantiated FMU (fmpy's object, its C functions, the status checks);
- ``solvers``: the model-exchange integrators (RK4/DOP853 fast path, CVode with events);
- ``coupled``: several model-exchange FMUs integrated as one system (one integrator, one
  event loop; what they exchange is the caller's);
- ``adapter``: one FMU behind one interface (co-simulation and model exchange, FMI 2.0 and
  3.0), on top of the modules above;
- ``proxy``: the same interface for an FMU in a worker process, with a time limit per call.

See ``docs/architecture.md``.
"""
