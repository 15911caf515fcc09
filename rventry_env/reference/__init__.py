"""The collocation reference: the paper's entry problem solved once and shipped.

* :func:`load_reference` - the shipped optimal trajectory (:class:`Reference`),
  cached; ``.t``, ``.x (n, 12)``, ``.u (n, 2)``, ``.tf``, ``.cost``,
  ``.state(t)``, ``.control(t)``, ``.summary()``. NumPy only.
* :func:`load_guidance_reference` - the same problem solved with 30 % / 6 % margins on
  the q and load-factor bounds: the feedforward the guidance laws track.
* :mod:`.collocation` - the general LGR collocation solver with hp refinement
  (CasADi + IPOPT, imported only when used).
* :mod:`.entry_ocp`, :mod:`.guess`, :mod:`.pipeline` - Example 2, its
  generated initial guess, and the cold-start solve that regenerates the file.
* :mod:`.betts_shuttle` - the solver's validation benchmark.
* :mod:`.spherical_entry` - the same problem in spherical coordinates (the singularity study).
* :mod:`.open_loop` - open-loop replay of the reference controls.
"""

from rventry_env.reference.data_file import (
    DEFAULT_PATH,
    GUIDANCE_PATH,
    Reference,
    load_guidance_reference,
    load_reference,
    read_reference,
)

__all__ = ["DEFAULT_PATH", "GUIDANCE_PATH", "Reference", "load_guidance_reference", "load_reference", "read_reference"]
