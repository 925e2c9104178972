"""The data model: photo blocks (photo_block.py), model blocks (model_block.py), lens models
(camera.py), camera models for self-calibration (camera_models.py), rotations (rotation.py)
and the local frame of a CRS (crs.py).
"""
