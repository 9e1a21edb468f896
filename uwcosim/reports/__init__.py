"""The report stage of a run: figures, ``report.md`` and ``report.html`` from a run directory's
files alone (``run_report.report_run``), the result table (``table``), the report of a plain
co-simulation run (``signal_report``), the run's HTML page (``html``), what a run directory
holds (``runfiles``) and the command that reproduces a run (``reproduce``). A campaign's report
is :mod:`uwcosim.campaign.report`; ``uwcosim report PATH`` (:func:`uwcosim.api.report`) picks
the kind from what the folder holds.
"""
