"""Relative orientation with scale transfer, model by model, with on-line quality control
(Kratky and El-Hakim 1983, NRC ANAPLOT).

    coplanarity.py     the coplanarity condition and its partials
    scale_transfer.py  the collinearity condition in the XZ plane at tie points
    orientation.py     one model: combined -> parametric form, Gauss-Newton, DenseModel
    qc.py              the QC of one model (quality layer + Qvv P + critical transfers)
    table.py           the ANAPLOT table as text
    session.py         OnlineSession: strip bridging model by model
    commands.py        the line language of `baarda online` (file or prompt)
    pattern.py         point-pattern design without measurements
    drawing.py         a pattern with its r values and critical transfers, text and SVG
    simulate.py        a simulated strip with known truth

Model coordinates are in the units of the first base (mm at photo scale by default), image
coordinates in mm, residuals and sigmas in µm, angles in rad (gon in reports).
"""
