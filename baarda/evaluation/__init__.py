"""Detection power, measured: Monte Carlo studies of blunder-detection strategies on
simulated blocks with known blunders (`baarda evaluate`, docs/evaluation.md)."""
