"""Tracing what no candidate explains to a force channel.

* :mod:`.forcing` - a generic correction, a piecewise-linear function of altitude or of time,
  added to the replay's specific force in one channel (drag, vertical lift, lateral lift,
  horizontal wind);
* :mod:`.attribution` - every channel and pair fitted with the entry state and the effects,
  knots chosen by BIC, the band and size of the winner, and the physical effects it points to.
"""
