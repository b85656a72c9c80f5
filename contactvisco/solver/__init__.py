"""Solving: the Newton solver over PETSc SNES (newton), the node-wise elimination of the
multipliers (condensed), the time loop (time_loop), what a run prints (report) and why a step
failed for good (diagnosis). Imports io, fem, scene, model.
"""
