"""The constitutive model, as formulas: the elasticity operator A (eq 7), the memory kernel R
and the history of eq (19), the contact law (eqs 11-12, 20-21) in UFL, and the stability of
the time rule. No mesh, no files; imports nothing of the package but errors.
"""
