"""Verification problems with known exact solutions (``uwcosim verify ...``)."""

from uwcosim.verify.example1 import Example1Result, run_example1

__all__ = ["Example1Result", "run_example1"]
