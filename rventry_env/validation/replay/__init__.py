"""Flying a record with the rv-Euler entry model.

* :mod:`.replay_setup` - the declared facts (vehicle, entry state, noise) from the sidecar;
* :mod:`.controls` - the record's angle of attack and bank as a schedule the replay follows;
* :mod:`.record_replay` - the RK4 replay on a grid independent of the sampling;
* :mod:`.sensitivity` - the same replay on CasADi symbols with exact forward-mode sensitivities.
"""
