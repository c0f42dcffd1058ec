"""Pictures: meshcat scenes of any closed-loop model (self-contained HTML) and
matplotlib figures.
"""
