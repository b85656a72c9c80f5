"""The range of the numbers a scene may give, shared by the key checks (scene.table) and the
expression parser (scene.expressions), which do not import each other's checks."""

#: Scene moduli (E, lambda, mu, stiffness, ...) and box sizes must lie in
#: [1/MODULUS_RANGE, MODULUS_RANGE], and the numbers of an expression within +-MODULUS_RANGE:
#: products of moduli, lengths, displacements and their squares then stay far inside double
#: precision (1e308).
MODULUS_RANGE = 1e100
