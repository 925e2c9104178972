"""The result-file contract, one place for every writer and reader: the columns of
observations.csv (and .parquet) of every method, and the unit of each kind's residuals.
summary.json states the units of its run ("units"); docs/format.md describes both."""

from __future__ import annotations

from baarda.kinds import unit_names

# observations.csv: one row per observation component, in this order
OBSERVATION_COLUMNS = (
    "adjustment", "kind", "photo", "model", "point", "component", "x_mm", "y_mm",
    "residual", "sigma", "sigma_residual", "redundancy", "w", "tau", "p_value", "mdb",
    "lambda_bar", "external_max", "external_point", "point_test", "rho_max", "rho_partner",
    "msb", "rejected", "flagged")
REQUIRED_COLUMNS = ("kind", "point", "component", "residual")  # what a reader needs
FRAME_COLUMNS = ("photo", "model")  # at least one of them: the photo or model of a row
NUMBER_COLUMNS = ("x_mm", "y_mm", "residual", "sigma", "sigma_residual", "redundancy", "w",
                  "tau", "p_value", "mdb", "lambda_bar", "external_max", "point_test",
                  "rho_max", "msb")
FLAG_COLUMNS = ("rejected", "flagged")
LABEL_COLUMNS = ("external_point", "rho_partner")  # text naming another point / observation

# the unit of the residual, sigma and MDB columns by kind (baarda/kinds.py; a run's
# summary.json "units" says what it wrote: IMU residuals in the project's angle unit / 1000)
UNITS = unit_names()
