"""current_nav: an AUV with a water current and a range beacon, for uwcosim (an example).

A user's package as uwcosim takes it (docs/your_own_model.md, docs/your_own_filter.md):

- ``equations``: the vehicle (position, water-relative velocity, a Gauss-Markov current) and the
  beacon range in CasADi, written once;
- ``fmus``: the truth FMUs' specifications (``uwcosim fmu build --spec current_nav.fmus:specs``);
- ``model``: the filters' model, ``build(context, ...)`` (``[model] type``), from
  :func:`uwcosim.models.from_casadi`;
- ``gated_ekf``: an EKF with an innovation gate (``[estimators.NAME] type``).

``pyproject.toml`` declares the last two as the entry points ``current_nav`` (group
``uwcosim.models``) and ``gated_ekf`` (group ``uwcosim.estimators``).
"""

__version__ = "0.1.0"
