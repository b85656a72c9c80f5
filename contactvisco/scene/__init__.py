"""A scene: one TOML document holding every parameter of a run, read, checked and filled with
defaults (tables), with expressions in x and t (expressions). Imports model and errors.
"""
