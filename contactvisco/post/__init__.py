"""Looking at results: matplotlib figures (figures), pyvista rendering (render), notebook
helpers (notebook). Reads what io writes; imports io and below, never solver.
"""
