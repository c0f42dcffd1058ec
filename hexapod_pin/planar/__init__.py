"""The planar 3-PRR: the seed's simplified model on the same generic core, and its
symbolic (sympy) Lagrangian derivation.
"""
