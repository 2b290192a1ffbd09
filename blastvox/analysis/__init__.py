"""Post-run analysis of SimCaches: error metrics between runs of the same shot."""
