"""What an identification hands back: the JSON report, diagnostics, plots and the model file.

* :mod:`.build` - the report, assembled from the phases' results;
* :mod:`.diagnostics` - error metrics and the record-specific checks (density, declared state);
* :mod:`.plots` - residual, ranking and density plots;
* :mod:`.model_io` - the identified :class:`~rventry_env.physics.EntryModel` to and from JSON.
"""
