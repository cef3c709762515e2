"""A motorway fleet: each vehicle's body type and footprint drawn from real traffic shares and dimensions.

Shares (of vehicles passing on a motorway; GB vehicle-kilometre shares as the nearest published measure):

* DfT, *Road traffic estimates in Great Britain 2023* (vehicle type release, chart 5): cars 76 %, vans
  (light commercial vehicles up to 3.5 t, pickups included) 17 %, lorries 5 %, buses and coaches 1 %,
  motorcycles 1 % of all motor-vehicle traffic. Motorways carry about twice their share of lorries (DfT,
  *Road traffic estimates 2012*: the Strategic Road Network carried 32.7 % of all traffic and 65.5 % of all
  lorry traffic), so lorries are taken as 10 %, artics (articulated HGVs) three in five of them;
  motorcycles are left out and the rest renormalised: cars 73 %, vans and pickups 16 %, HGVs 10 %, buses 1 %.
* Cars split by body type as the European car stock lags new registrations (JATO Dynamics: SUVs 38.3 % of
  European new-car registrations in 2019, 44 % in January 2021, subcompact hatchbacks 19 %): hatchbacks
  40 %, SUVs 32 %, saloons 15 %, estates 13 % of cars. Pickups are about 1.5 % of GB traffic (one van in ten).

=========  =====  =====================  ======================  ==========================
body       share  length (m): mean, sd,  body width (m): mean,   typical of
                  range                  sd, range
=========  =====  =====================  ======================  ==========================
hatchback  0.29   4.05, 0.25, 3.55-4.45  1.76, 0.05, 1.64-1.84   Polo, Golf, Clio, Corsa
saloon     0.11   4.72, 0.16, 4.40-5.05  1.82, 0.04, 1.74-1.90   3 Series, A4, Passat
estate     0.10   4.70, 0.14, 4.45-5.00  1.81, 0.04, 1.74-1.88   Octavia Combi, Passat Variant
suv        0.23   4.45, 0.22, 4.05-4.95  1.84, 0.06, 1.74-2.00   T-Roc, Qashqai, Tiguan, X5
van        0.145  5.35, 0.62, 4.40-6.95  1.98, 0.06, 1.80-2.07   Berlingo, Transit, Sprinter
pickup     0.015  5.40, 0.22, 5.10-5.95  1.88, 0.05, 1.80-2.03   Hilux, Ranger, F-150
box_truck  0.04   8.60, 1.10, 7.00-10.8  2.50, 0.03, 2.40-2.55   7.5-26 t rigid lorries
artic      0.06   16.3, 0.25, 15.5-16.5  2.55, 0.01, 2.50-2.55   EU 16.5 m / 2.55 m limits
bus        0.01   12.0, 0.60, 10.5-13.5  2.55, 0.01, 2.50-2.55   city buses, coaches
=========  =====  =====================  ======================  ==========================

Dimensions are the manufacturers' figures of the types' best-sellers and the EU limits (Directive
96/53/EC: 16.5 m articulated, 2.55 m wide). Length and body width are drawn from normals with correlation
0.6 (a longer model is also wider), clipped to the range, rounded to the cm. A light vehicle's footprint
is its body width plus :data:`MIRRORS_M` (its mirrors, the widest part of its mesh); a heavy vehicle's box
is its full width. The body's height, clearance, wheels and overhangs follow from the footprint
(:func:`harness.world.vehicles.vehicle_layout`).
"""

from __future__ import annotations

import numpy as np

from harness.world.vehicles import BODY_TYPES, HEAVY_BODIES

#: Share of each body type in motorway traffic (sums to 1), in :data:`BODY_TYPES` order.
SHARES = {"hatchback": 0.29, "saloon": 0.11, "estate": 0.10, "suv": 0.23, "van": 0.145, "pickup": 0.015,
          "box_truck": 0.04, "artic": 0.06, "bus": 0.01}
#: Per body type: (length mean, sd, lo, hi), (body width mean, sd, lo, hi), m.
DIMENSIONS = {
    "hatchback": ((4.05, 0.25, 3.55, 4.45), (1.76, 0.05, 1.64, 1.84)),
    "saloon": ((4.72, 0.16, 4.40, 5.05), (1.82, 0.04, 1.74, 1.90)),
    "estate": ((4.70, 0.14, 4.45, 5.00), (1.81, 0.04, 1.74, 1.88)),
    "suv": ((4.45, 0.22, 4.05, 4.95), (1.84, 0.06, 1.74, 2.00)),
    "van": ((5.35, 0.62, 4.40, 6.95), (1.98, 0.06, 1.80, 2.07)),
    "pickup": ((5.40, 0.22, 5.10, 5.95), (1.88, 0.05, 1.80, 2.03)),
    "box_truck": ((8.60, 1.10, 7.00, 10.8), (2.50, 0.03, 2.40, 2.55)),
    "artic": ((16.3, 0.25, 15.5, 16.5), (2.55, 0.01, 2.50, 2.55)),
    "bus": ((12.0, 0.60, 10.5, 13.5), (2.55, 0.01, 2.50, 2.55)),
}
#: Correlation of a type's length and width draws.
RHO = 0.6
#: What a light vehicle's mirrors add to its body width (m): its footprint's width.
MIRRORS_M = 0.17
_TAG = 0xF1EE7

assert tuple(SHARES) == BODY_TYPES and abs(sum(SHARES.values()) - 1.0) < 1e-12


def vehicle_rng(seed: int, vehicle_id: int) -> np.random.Generator:
    """The generator of one vehicle's body and footprint: a pure function of the scenario seed and its id."""
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, int(vehicle_id) & 0xFFFFFFFF, _TAG])


def typical_dimensions(body: str, rng: np.random.Generator) -> tuple[float, float]:
    """(length, footprint width) in m of a vehicle of type ``body``, drawn from :data:`DIMENSIONS`."""
    if body not in DIMENSIONS:
        raise ValueError(f"body {body!r} is not one of {', '.join(BODY_TYPES)}")
    (lm, ls, llo, lhi), (wm, ws, wlo, whi) = DIMENSIONS[body]
    z1, z2 = rng.standard_normal(2)
    length = float(np.clip(lm + ls * z1, llo, lhi))
    width = float(np.clip(wm + ws * (RHO * z1 + np.sqrt(1.0 - RHO ** 2) * z2), wlo, whi))
    if body not in HEAVY_BODIES:
        width += MIRRORS_M
    return round(length, 2), round(width, 2)


def draw_body(rng: np.random.Generator) -> tuple[str, float, float]:
    """(body type, length m, footprint width m) of one vehicle of the motorway fleet."""
    p = np.array([SHARES[b] for b in BODY_TYPES])
    body = BODY_TYPES[int(rng.choice(len(BODY_TYPES), p=p / p.sum()))]
    return (body, *typical_dimensions(body, rng))
