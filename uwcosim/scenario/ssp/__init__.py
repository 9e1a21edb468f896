"""SSP files (1.0 and 2.0) as the truth side of a scenario: the XML (``xml``), its records
(``tree``) checked against fmpy's schemas (``schema``), the parameter bindings (``params``),
the flat FMU network (``read``) and the scenario data it becomes (``convert``). See
``docs/ssp.md``."""
