"""Independent-model block adjustment (FOTEF): pre-adjustment, spatial and planimetric +
height adjustment, data snooping, model deformations and external reliability.
"""
