"""The references a record's entry state may be read on, and what a fitted entry-state offset points to.

The model's Earth is a sphere of the equatorial radius. A record's altitudes, and the sidecar's
entry state, may have been written on the Earth's figure instead: geodetic height over the WGS-84
ellipsoid, a flight-path angle from the geodetic horizon, a speed in the inertial frame. Between
two such readings of one state lie known, physical offsets:

* **altitude reference**: at geocentric latitude phi the WGS-84 surface lies
  ``R_eq - r_s(phi)`` inside the model's sphere, ``r_s = a b / sqrt(b^2 cos^2 phi + a^2 sin^2 phi)``
  (0 at the equator, 3.4 km at 23.7 deg, 21.4 km at the poles): a geodetic altitude reads that
  much higher than the same point's altitude over the sphere. An entry state and a record read on
  different references disagree by it. (Geodetic height is measured along the ellipsoid's normal,
  not the radius; at entry altitudes the two differ by less than a metre.)
* **horizon reference**: the geodetic vertical leans from the geocentric one by
  ``psi = phi_geodetic - phi_geocentric`` (0.19 deg at 45 deg latitude) in the meridian, so a
  flight-path angle read from the geodetic horizon differs by ``psi cos(azimuth)``.
* **frame**: an inertial speed exceeds the Earth-relative one by about the Earth's rotation speed
  along the track (:func:`frame_speed_difference`); that one is a frame error the intake refuses
  (:mod:`~rventry_env.validation.intake.consistency`), not an offset to fit.

:func:`explain_entry_offset` compares the entry-state offset a fit found with these, so a sidecar
that disagrees with its record is traced to the reference it was read on when the record
supports it, and reported as an unexplained offset when not.
"""

from __future__ import annotations

import math

import numpy as np

WGS84_A = 6378137.0  # m, equatorial radius
WGS84_F = 1.0 / 298.257223563
WGS84_B = WGS84_A * (1.0 - WGS84_F)  # m, polar radius
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)  # first eccentricity squared
ALTITUDE_REFERENCE_MAX_M = WGS84_A - WGS84_B  # 21 384.7 m: geodetic against the sphere, at the poles
AGREEMENT_SIGMAS = 3.0  # an offset agrees with a reference within this many standard errors


def ellipsoid_radius(latitude: float) -> float:
    """Geocentric radius (m) of the WGS-84 surface at geocentric ``latitude`` (rad)."""
    c, s = math.cos(latitude), math.sin(latitude)
    return WGS84_A * WGS84_B / math.sqrt((WGS84_B * c) ** 2 + (WGS84_A * s) ** 2)


def altitude_reference_offset(latitude: float, radius: float = WGS84_A) -> float:
    """How much higher a geodetic (WGS-84) altitude reads than the altitude over a sphere of ``radius`` (m).

    :param latitude: geocentric latitude (rad).
    :param radius: the model's sphere (the equatorial radius by default).
    """
    return radius - ellipsoid_radius(latitude)


def horizon_deflection(latitude: float) -> float:
    """Geodetic minus geocentric latitude (rad) at geocentric ``latitude``: the lean of the geodetic vertical."""
    geodetic = math.atan2(math.tan(latitude), 1.0 - WGS84_E2) if abs(math.cos(latitude)) > 1e-12 else latitude
    return geodetic - latitude


def frame_speed_difference(speed: float, altitude: float, latitude: float, flight_path: float, azimuth: float,
                           planet) -> float:  # fmt: skip
    """Inertial minus Earth-relative speed (m/s) of a state moving at Earth-relative ``speed`` in this direction.

    The inertial velocity is v_E + w x r: the Earth's rotation speed ``omega r cos(latitude)`` added
    eastward.
    """
    r = planet.radius + altitude
    east = speed * math.cos(flight_path) * math.sin(azimuth) + planet.omega * r * math.cos(latitude)
    north = speed * math.cos(flight_path) * math.cos(azimuth)
    up = speed * math.sin(flight_path)
    return math.sqrt(east * east + north * north + up * up) - speed


def _agreement(value: float, stderr: float, predicted: float) -> float:
    return abs(value - predicted) / stderr if stderr > 0 else math.inf


def _reference_readings(dh: float, se_h: float, dg: float, se_g: float, early, d_alt: float, u_ref: float,
                        psi: float) -> list[dict]:  # fmt: skip
    """Each reference's reading of the offset (the altitude reference either way round, the horizon
    reference either way round), its prediction and how many standard errors the fit lies from it."""
    references = []
    for sign, reading in ((1.0, "the record's altitudes (and the atmosphere it flew) are geodetic, over the WGS-84 "
                                "ellipsoid, and the sidecar's altitude is over the model's sphere"),
                          (-1.0, "the sidecar's altitude is geodetic, over the WGS-84 ellipsoid, and the record's "
                                 "altitudes (and the atmosphere it flew) are over the model's sphere")):  # fmt: skip
        pred = sign * d_alt
        z = _agreement(dh, math.hypot(se_h, u_ref), pred)
        z_early = _agreement(early[0], math.hypot(early[1], u_ref), pred) if early else None
        references.append({"reference": "altitude_reference", "component": "dh0_m", "predicted": pred,
                           "uncertainty": u_ref, "reading": reading, "z": z, "z_first_samples": z_early,
                           "agrees": bool(z <= AGREEMENT_SIGMAS)})  # fmt: skip
    for sign, reading in ((1.0, "the sidecar's flight-path angle is read from the geocentric horizon and the record "
                                "flew the geodetic one"),
                          (-1.0, "the sidecar's flight-path angle is read from the geodetic horizon")):  # fmt: skip
        pred = sign * psi
        z = _agreement(dg, se_g, pred)
        references.append({"reference": "horizon_reference", "component": "dgamma0_rad", "predicted": pred,
                           "reading": reading, "z": z, "agrees": bool(z <= AGREEMENT_SIGMAS)})  # fmt: skip
    return references


def _offset_statement(fitted: dict, se: dict, early, explained: list, significant: bool, latitude: float,
                      d_alt: float, u_ref: float) -> str:  # fmt: skip
    """The statement of the fitted offset: its size, and the altitude reference that explains it or
    that none does."""
    dh, se_h = fitted["dh0_m"], se["dh0_m"]
    dg, se_g = fitted["dgamma0_rad"], se["dgamma0_rad"]
    lat_deg = math.degrees(latitude)
    where = f"{abs(lat_deg):.1f} deg {'N' if lat_deg >= 0 else 'S'}"
    text = (f"The fitted entry state is {dh:+.4g} +/- {se_h:.2g} m in altitude, {fitted['dv0_mps']:+.4g} +/- "
            f"{se['dv0_mps']:.2g} m/s in speed and {math.degrees(dg):+.3g} +/- {math.degrees(se_g):.2g} deg in "
            "flight-path angle from the sidecar's")  # fmt: skip
    text += (f" (the first samples alone: {early[0]:+.4g} +/- {early[1]:.2g} m)." if early else ".")
    if explained:
        r = explained[0]
        text += (f" The altitude offset agrees with the altitude reference at {where} ({r['predicted']:+.4g} +/- "
                 f"{u_ref:.2g} m, {r['z']:.1f} standard errors away): {r['reading']}.")  # fmt: skip
    elif significant:
        text += (f" No altitude reference explains it (the WGS-84 surface lies {d_alt:.4g} m inside the model's "
                 f"sphere at {where}): a reading error, a time tag or a state converted in another frame "
                 "remain.")  # fmt: skip
    return text


def explain_entry_offset(names, values, stderr, setup, inflation: float = 1.0, check: dict | None = None) -> dict:
    """The fitted entry-state offset of a reduced record, its uncertainty, and the references it agrees with.

    The fit's altitude offset (its standard error inflated for a correlated residual) is compared
    with each reference, whose own uncertainty is what the declared latitude leaves open (geodetic
    or geocentric: they differ by the horizon deflection, which moves the reference by
    dR/dphi psi, 38 m at 23.7 deg). The robust line through the first samples against the
    declared state (``check``), which needs no model beyond the first seconds, is reported beside
    it and counts for the offset's significance; its standard error holds only the scatter about
    a straight line, not how the declared state's replay departs from one, so it is not used to
    judge agreement. A reference explains the offset when the offset is significant, the
    reference is not zero within its uncertainty, and the fit agrees with it within
    :data:`AGREEMENT_SIGMAS` standard errors.

    :param names: the fit's initial-state parameter names (``dh0_m``, ``dv0_mps``, ``dgamma0_rad``).
    :param values: their fitted values.
    :param stderr: their standard errors (from the fit's covariance, white residual).
    :param setup: the declared facts (the sidecar's entry state and the model's planet).
    :param inflation: factor on the standard errors for a correlated residual (sqrt(n / n_eff)).
    :param check: the intake's comparison of the declared state with the first samples, if any.
    :return: the report's ``entry_state_offset`` section.
    """
    es = setup.entry_state
    planet = setup.model.planet
    check = check or {}
    fitted = dict(zip(names, map(float, values)))
    se = {k: float(s) * inflation for k, s in zip(names, stderr)}
    dh, se_h = fitted["dh0_m"], se["dh0_m"]
    dg, se_g = fitted["dgamma0_rad"], se["dgamma0_rad"]
    early = None
    if "altitude_difference_m" in check:
        early = (float(check["altitude_difference_m"]), float(check["altitude_difference_stderr_m"]))
    d_alt = altitude_reference_offset(es.latitude, planet.radius)
    # the declared latitude may be geodetic or geocentric: the reference's own uncertainty
    u_ref = abs(altitude_reference_offset(es.latitude + horizon_deflection(es.latitude), planet.radius) - d_alt)
    psi = horizon_deflection(es.latitude) * math.cos(es.azimuth)
    references = _reference_readings(dh, se_h, dg, se_g, early, d_alt, u_ref, psi)
    significant = abs(dh) > AGREEMENT_SIGMAS * se_h
    significant |= early is not None and abs(early[0]) > AGREEMENT_SIGMAS * early[1]
    resolved = d_alt > AGREEMENT_SIGMAS * math.hypot(min(se_h, early[1] if early else math.inf), u_ref)
    explained = [r for r in references if r["component"] == "dh0_m" and r["agrees"] and significant and resolved]
    text = _offset_statement(fitted, se, early, explained, significant, es.latitude, d_alt, u_ref)
    return {
        "offsets": {k: {"value": fitted[k], "stderr": se[k]} for k in names},
        "stderr_inflation": inflation,
        "first_samples": None if early is None else {"altitude_difference_m": early[0], "stderr_m": early[1],
                                                     "t_s": check.get("t_s")},
        "declared": {"altitude_m": es.altitude, "speed_rel_mps": es.speed,
                     "flight_path_angle_deg": math.degrees(es.flight_path)},
        "fitted": {"altitude_m": es.altitude + dh, "speed_rel_mps": es.speed + fitted["dv0_mps"],
                   "flight_path_angle_deg": math.degrees(es.flight_path + dg)},
        "prior_widened": sorted(check.get("widen", {})),
        "significant": bool(significant),
        "altitude_reference_m": d_alt,
        "horizon_deflection_rad": psi,
        "references": references,
        "explained_by": [r["reference"] for r in explained],
        "statement": text,
    }  # fmt: skip


__all__ = [
    "ALTITUDE_REFERENCE_MAX_M",
    "WGS84_A",
    "WGS84_B",
    "altitude_reference_offset",
    "ellipsoid_radius",
    "explain_entry_offset",
    "frame_speed_difference",
    "horizon_deflection",
]
