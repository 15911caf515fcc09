"""Tracing the residual to an effect: candidates, fits, selection, aliases, and what remains.

* :mod:`.effects` - the candidate effects, their parameters and physical bounds, the model they build;
* :mod:`.fit` - output-error least squares with exact sensitivities;
* :mod:`.selection` - the shared fit context, plausibility, and the BIC comparison;
* :mod:`.aliases` - what a trajectory can tell apart;
* :mod:`.phases` - the search itself, one named phase per function;
* :mod:`.adequacy` - the final residual against the noise;
* :mod:`.statistics` - noise estimators, BIC, whiteness.
"""
