"""Synthetic records with undeclared effects, through an independent Cartesian truth model.

* :mod:`.truth` - the test oracle (the one deliberate second copy of the entry physics);
* :mod:`.simulate` - a scripted CAV-H flight through it, written as a record with noise.
"""
