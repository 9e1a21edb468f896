"""Figures of runs and campaigns (matplotlib, Agg backend), small modules by subject."""
