"""Bundle block adjustment: the collinearity equations, the problem of the solver, free
networks, space resection, the result and its view for the quality layer.
"""
