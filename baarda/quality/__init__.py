"""The statistics of every adjusted model, written once: the AdjustedModel contract,
redundancy numbers, w and tau tests, MDB, external reliability, hypothesis tests, data
snooping, robust re-weighting, Gruen's modified snooping and the Assessment results.
"""
