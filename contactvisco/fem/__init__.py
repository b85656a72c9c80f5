"""The discrete problem on a mesh: the mesh and its boundary tags (geometry), the forms and
spaces (problem), the free rigid motions (rigid), and what differs between DOLFINx versions
(compat). Imports scene, model and errors.
"""
