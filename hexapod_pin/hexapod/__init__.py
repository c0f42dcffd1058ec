"""The rail-driven 6-DoF hexapod: geometry, closed forms, tree routes, the :class:`Hexapod`
facade, simulation and workspace analysis.
"""
