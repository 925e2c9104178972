"""Readers of every supported input (native projects, COLMAP, BAL, DBAT, PhotoModeler,
AICON, model projects); they return data-model objects and import no computation.
"""
