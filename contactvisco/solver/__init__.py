"""Solving: the Newton solver over PETSc SNES (newton), the node-wise elimination of the
multipliers (condensed), and the time loop (time_loop). Imports io, fem, scene, model.
"""
