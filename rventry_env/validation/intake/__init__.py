"""What a record goes through before any fit.

* :mod:`.noise` - the observation groups, the record's noise, and how far the entry state may move;
* :mod:`.outliers` - gross outliers rejected by file line;
* :mod:`.consistency` - the sidecar's entry state against the first samples;
* :mod:`.prepare` - these steps in order, ending in the context every fit shares.
"""
