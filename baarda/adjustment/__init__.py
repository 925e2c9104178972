"""The one solver (solve.py), the point-eliminated normal equations (schur.py) and the
small dense problems (dense.py): what every method adjusts on.
"""
