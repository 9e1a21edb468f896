"""SSP files as the truth side of a scenario: the XML (``xml``), the flat FMU network
(``read``) and the scenario data it becomes (``convert``). See ``docs/ssp.md``."""
