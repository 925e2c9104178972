"""Numbers printed in Salsig (1989), read from /work/shared/seeds/004_67166935f872f180.txt.

Figure 1: ground control residuals (m) of a BINGO adjustment, with VAN's summary.
Figure 3: counts of the image x residual histogram, classes of 1 µm from -25 to +25.
"""

# point, vX, vY, vZ (m); points 114-124 are height points (no X, Y)
FIG1_CONTROL = """point,vX,vY,vZ
301,0.059,-0.030,0.022
302,-0.025,-0.052,-0.024
303,0.019,0.009,-0.054
304,-0.052,-0.025,0.082
305,-0.008,0.022,-0.040
306,-0.026,-0.022,0.023
307,-0.025,-0.036,-0.141
308,0.012,0.010,-0.045
309,0.042,0.005,-0.038
310,0.011,0.009,0.020
311,0.044,-0.004,-0.004
312,-0.006,0.103,0.013
313,-0.045,0.011,-0.058
114,,,-0.047
115,,,0.058
116,,,0.036
117,,,0.101
118,,,0.026
119,,,0.055
120,,,0.029
121,,,-0.024
122,,,0.050
123,,,0.009
124,,,-0.049
"""

# VAN's printed summary of Figure 1: X, Y, Z
FIG1_RMS = (0.033, 0.037, 0.053)
FIG1_AVERAGE = (0.000, 0.000, 0.000)
FIG1_NUMBER = (13, 13, 24)
FIG1_MINIMUM = (-0.052, -0.052, -0.141)
FIG1_MAXIMUM = (0.059, 0.103, 0.101)

# Figure 3: number of image x residuals per 1-µm class (classes not listed: 0).
# They add up to 318, while Figure 2 says "NUMBER OF IMAGES = 338": the OCR text does not
# tell whether a count was lost or the 338 counts something else.
FIG3_X_COUNTS = {-13: 1, -10: 1, -9: 1, -8: 3, -7: 7, -6: 9, -5: 8, -4: 18, -3: 17, -2: 24,
                 -1: 37, 0: 70, 1: 45, 2: 14, 3: 20, 4: 17, 5: 7, 6: 9, 7: 5, 8: 2, 9: 2,
                 10: 1}
# Figure 2, component X (mm): average 0.000, RMS 0.003, min -0.013, max 0.010
FIG2_X = {"average": 0.000, "rms": 0.003, "min": -0.013, "max": 0.010}
