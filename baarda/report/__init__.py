"""The adjustment report (text and HTML) and the residual post-processor: renders a result
folder, never recomputes a statistic.
"""
