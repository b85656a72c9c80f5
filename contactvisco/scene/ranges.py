"""Ranges of scene values shared by the table checks (contactvisco.scene.table) and the
expression whitelist (contactvisco.scene.expressions), which both import it: the second is
imported by the first only where an expression is checked, and neither imports the other at
load time, so there is no import circle between them."""

#: Scene moduli (E, lambda, mu, stiffness, ...) and box sizes must lie in
#: [1/MODULUS_RANGE, MODULUS_RANGE]: products of moduli, lengths, displacements and their
#: squares then stay far inside double precision.
MODULUS_RANGE = 1e100
