"""What a run reads and writes: per-step output and the contact table (output), checkpoints
(checkpoint), the output folder's lock (lock), files opened without following links,
regular files only (files), every rank's agreement on a failure and on
signals (parallel), reading HDF5 results back (h5read). Imports fem, scene, model, errors.
"""
