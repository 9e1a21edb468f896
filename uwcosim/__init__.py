"""uwcosim: a co-simulation testbench for underwater navigation filters.

The truth side (AUV kinematics and sensors) runs as FMUs stepped by our own master on fmpy;
the estimation side is a library of Bayesian filters (``uwcosim.filters``); every run is logged
to Parquet with its metadata (``uwcosim.runlog``).
"""

__version__ = "0.1.0"
