"""Relative orientation with scale transfer, model by model, with on-line quality control
(Kratky and El-Hakim 1983, NRC ANAPLOT).

    coplanarity.py      the coplanarity condition and its partials
    scale_transfer.py   the collinearity condition in the XZ plane at tie points
    orientation.py      one model: combined -> parametric form, solved by the one solver
    model_qc.py         the QC of one model (quality layer + Qvv P + critical transfers)
    model_report.py     the ANAPLOT table of one model as text
    session.py          OnlineSession: strip bridging model by model
    online_commands.py  the line language of `baarda online` (file or prompt)
    point_pattern.py    point-pattern design without measurements
    pattern_drawing.py  a pattern with its r values and critical transfers, text and SVG

A simulated strip with known truth is in baarda/simulate/online_strip.py.  Model
coordinates are in the units of the first base (mm at photo scale by default), image
coordinates in mm, residuals and sigmas in µm, angles in rad (gon in reports).
"""
