"""Symbolic models (CasADi) shared by the FMUs and the estimators: equations defined once."""
