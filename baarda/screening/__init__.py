"""Sequential screening before the bundle (Lugnani and Mitishita): photo pairs, strip
formation, control, and the chain's bundle snooping with separability.
"""
