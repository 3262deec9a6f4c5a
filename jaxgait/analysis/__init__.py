"""Layer 7: measures, criteria, human reference data, plots, trajectories, robustness."""
