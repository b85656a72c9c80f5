"""Studies built on whole runs: the speed-accuracy trade of a scene (tradeoff), verification
against closed forms (verification), Coulomb friction closed forms (coulomb). Import solver
and below.
"""
