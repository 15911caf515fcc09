"""Small application utilities every room may use: argument checks and whole-file outputs.

Nothing here knows about the physics, the environments or the solvers.
"""
