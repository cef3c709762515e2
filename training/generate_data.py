"""Render varied scenarios with the harness into a detector training/validation set.

Each scenario draws (deterministically from ``--seed`` and its index): lanes 2-5,
ego lane and speed, random traffic (count, density), 1-4 placed vehicles at
4-70 m (so near, large and far, small vehicles are all present; sizes from cars
to trucks), camera height 1.1-1.8 m, pitch 0-6 deg, hfov 50-90 deg, a resolution,
palette seed, light direction/intensity, sensor noise and blur. Every
``--stride``-th frame of its simulation is rendered, letterboxed to the net's input
(320x192, :class:`monorarp.detection.letterbox.Letterbox`) and stored with the
tight boxes of the visible pixels of every vehicle (from the renderer's id mask,
source pixels). A box is *required* when its visibility (visible / unoccluded,
unbounded pixels) is >= ``--min-visibility`` and its height and width at the
net's scale are >= ``--min-size`` px; other visible vehicles are stored as *ignored*.
With ``--conditions P`` a fraction P of the scenarios also gets a random ``conditions:``
block (time of day, fog 40-1000 m, rain, motion blur, JPEG; :func:`random_conditions`),
drawn from its own random stream so the rest of each scenario is unchanged; boxes stay
those of the id pass, so vehicles hidden by fog or darkness are still labelled.
With ``--appearance P`` a fraction P of the scenarios gets a random appearance style
(:mod:`training.appearance`: paint, ground and sky tones, road texture, camera response) and
wider placed-vehicle dimensions (:func:`random_dimensions`), again from their own random stream;
``--appearance-family heldout`` draws the styles from the held-out family instead (validation only),
``none`` renders the same scenes unstyled.
With ``--look realistic`` every scenario is rendered with the realistic look (:mod:`harness.render.look`:
textured road, roadside, sky, sun shadows, detailed vehicles, sensor model) of ``--look-family``, its
look seed drawn from the scenario's own random stream; ``--conditions``/``--appearance`` do not combine with it.
With ``--fleet mixed`` the traffic is a real motorway fleet (``traffic.fleet: mixed``, :mod:`harness.world.fleet`:
hatchbacks, saloons, estates, SUVs, vans, pickups, box trucks, artics, buses) and every placed vehicle's body
and footprint is drawn from the same fleet (its own random stream).
With ``--street P`` a fraction P of the scenarios are urban streets (:func:`streetify`: 1-2 narrow lanes, parked
cars along the kerbs, pavements and, in the realistic look, the street frontage), from their own random stream;
with ``--street-bays Q`` a fraction Q of those park in angled or perpendicular bays (:func:`add_bays`).

    python -m training.generate_data --out data/train --scenarios 300 --seed 0
    python -m training.generate_data --out data/val --scenarios 40 --seed 100000 --resolutions 640x360
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import time
from pathlib import Path

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np  # noqa: E402
from scipy import ndimage  # noqa: E402

from harness.render.renderer import Renderer  # noqa: E402
from harness.world.scenario import ScenarioError, parse_scenario  # noqa: E402
from harness.simulation.simulator import simulate  # noqa: E402
from monorarp.core import boxes as box_ops  # noqa: E402
from monorarp.detection.fovea import Fovea  # noqa: E402
from monorarp.detection.letterbox import Letterbox  # noqa: E402
from training import appearance  # noqa: E402

NET_W, NET_H = 320, 192
TRAIN_RESOLUTIONS = ((640, 360), (640, 360), (960, 540), (1280, 720), (640, 480), (800, 450))


def scenario_dict(rng: np.random.Generator, index: int, seed: int, resolution: tuple[int, int]) -> dict:
    """One random scenario (a plain dict for :func:`parse_scenario`)."""
    lanes = int(rng.integers(2, 6))
    ego_lane = int(rng.integers(0, lanes))
    ego_speed = float(rng.uniform(15, 32))
    placed = []
    used = set()
    for k in range(int(rng.integers(1, 5))):
        rel = int(rng.integers(-ego_lane, lanes - ego_lane))
        d = float(np.exp(rng.uniform(np.log(4.0), np.log(70.0))))
        if (rel, round(d / 8)) in used:
            continue
        used.add((rel, round(d / 8)))
        big = rng.random() < 0.2
        placed.append({
            "name": f"p{k}", "lane": rel, "distance_m": round(d, 2),
            "speed_mps": round(max(0.0, ego_speed + float(rng.normal(0, 1.5))), 2),
            "behaviour": "idm", "lane_changes": False,
            "length_m": round(float(rng.uniform(8, 16) if big else rng.uniform(3.8, 5.6)), 2),
            "width_m": round(float(rng.uniform(2.3, 2.6) if big else rng.uniform(1.6, 2.1)), 2),
        })
    w, h = resolution
    az = rng.uniform(0, 2 * math.pi)
    elev = rng.uniform(0.3, 1.3)
    return {
        "name": f"gen{seed}_{index}", "seed": int(seed * 1000 + index), "duration_s": 30.0, "fps": 15.0,
        "road": {"lanes": lanes, "lane_width_m": round(float(rng.uniform(3.4, 4.2)), 2), "length_m": 3000.0},
        "traffic": {"vehicles_count": int(rng.integers(4, 30)), "density": round(float(rng.uniform(0.7, 2.5)), 2),
                    "speed_range_mps": [round(ego_speed - 5, 1), round(ego_speed + 5, 1)]},
        "ego": {"lane": ego_lane, "speed_mps": round(ego_speed, 2)},
        "vehicles": placed,
        "camera": {"width": w, "height": h, "hfov_deg": round(float(rng.uniform(50, 90)), 1),
                   "height_m": round(float(rng.uniform(1.1, 1.8)), 3),
                   "pitch_deg": round(float(rng.uniform(0, 6)), 2),
                   "forward_offset_m": round(float(rng.uniform(0.0, 1.5)), 2)},
        "render": {"palette_seed": int(rng.integers(0, 1_000_000)),
                   "light_direction": [round(math.cos(az) * math.cos(elev), 3), round(math.sin(az) * math.cos(elev), 3),
                                       round(-math.sin(elev), 3)],
                   "light_intensity": round(float(rng.uniform(1.5, 5.0)), 2),
                   "noise_std": round(float(rng.choice([0.0, 0.0, rng.uniform(0.5, 6.0)])), 2),
                   "blur_px": round(float(rng.choice([0.0, 0.0, 0.0, rng.uniform(0.3, 1.2)])), 2)},
    }


def random_conditions(rng: np.random.Generator) -> dict:
    """A random ``conditions:`` block (see :class:`harness.world.scenario.Conditions`)."""
    tod = str(rng.choice(["day", "low_sun", "dusk", "night"], p=[0.35, 0.2, 0.25, 0.2]))
    out: dict = {"time_of_day": tod}
    if rng.random() < 0.5:
        out["fog_visibility_m"] = round(float(np.exp(rng.uniform(np.log(40.0), np.log(1000.0)))), 1)
    if rng.random() < 0.3:
        out["rain"] = round(float(rng.uniform(0.2, 1.0)), 2)
    if rng.random() < 0.3:
        out["exposure_s"] = round(float(rng.uniform(0.002, 0.02)), 4)
    if rng.random() < 0.3:
        out["jpeg_quality"] = int(rng.integers(30, 90))
    return out


def densify(rng: np.random.Generator, sd: dict) -> None:
    """Make a :func:`scenario_dict` scenario dense occluding traffic, in place: at least 3 lanes, 25-50
    vehicles at density 2-3.5, and 1-3 pairs of placed cars in adjacent lanes at 20-70 m, the far one
    2-12 m behind the near one, so that the near car hides part of the far one (as in ``dense_traffic``)."""
    sd["road"]["lanes"] = max(3, sd["road"]["lanes"])
    ego_lane, lanes = sd["ego"]["lane"], sd["road"]["lanes"]
    speed = sd["ego"]["speed_mps"]
    sd["traffic"]["vehicles_count"] = int(rng.integers(25, 51))
    sd["traffic"]["density"] = round(float(rng.uniform(2.0, 3.5)), 2)
    placed = sd["vehicles"]
    for k in range(int(rng.integers(1, 4))):
        near = int(rng.integers(-ego_lane, lanes - ego_lane))
        far = near + int(rng.choice([-1, 1]))
        if not -ego_lane <= far < lanes - ego_lane:
            far = near - (far - near)
        d = float(rng.uniform(20, 70))
        for rel, dist in ((near, d), (far, d + float(rng.uniform(2, 12)))):
            if any(v["lane"] == rel and abs(v["distance_m"] - dist) < 8 for v in placed):
                continue
            placed.append({"name": f"o{k}_{len(placed)}", "lane": rel, "distance_m": round(dist, 2),
                           "speed_mps": round(max(0.0, speed + float(rng.normal(0, 1.0))), 2),
                           "behaviour": "idm", "lane_changes": False,
                           "length_m": round(float(rng.uniform(3.8, 5.6)), 2),
                           "width_m": round(float(rng.uniform(1.6, 2.1)), 2)})


def streetify(rng: np.random.Generator, sd: dict) -> None:
    """Make a :func:`scenario_dict` scenario an urban street, in place (``road.street``,
    :mod:`harness.simulation.parking`, :mod:`harness.render.street`): 1-2 lanes 2.75-3.5 m wide, parking strips
    2.3-2.7 m with 4-16 parked cars per 100 m on both sides (one in five: the right only), pavements 1.5-4 m;
    the ego at 6-14 m/s among 2-10 slow vehicles; the placed vehicles kept where their lane still exists."""
    lanes = int(rng.integers(1, 3))
    ego_lane = int(rng.integers(0, lanes))
    speed = float(rng.uniform(6, 14))
    sd["road"] = {"lanes": lanes, "lane_width_m": round(float(rng.uniform(2.75, 3.5)), 2), "length_m": 3000.0,
                  "shoulder_width_m": round(float(rng.uniform(2.3, 2.7)), 2), "speed_limit_mps": 14.0,
                  "street": {"parking": "right" if rng.random() < 0.2 else "both",
                             "parked_per_100m": round(float(rng.uniform(4, 16)), 1),
                             "facing_traffic_share": round(float(rng.uniform(0.6, 0.95)), 2),
                             "pavement_m": round(float(rng.uniform(1.5, 4.0)), 2)}}
    sd["ego"] = {"lane": ego_lane, "speed_mps": round(speed, 2)}
    sd["traffic"] = {"vehicles_count": int(rng.integers(2, 11)), "density": round(float(rng.uniform(0.6, 1.5)), 2),
                     "speed_range_mps": [round(max(speed - 3, 0.0), 1), round(speed + 3, 1)]}
    sd["vehicles"] = [v | {"speed_mps": round(max(0.0, speed + float(rng.normal(0, 1.5))), 2)}
                      for v in sd["vehicles"] if -ego_lane <= v["lane"] < lanes - ego_lane]


def add_bays(rng: np.random.Generator, sd: dict) -> None:
    """Park a :func:`streetify` street in angled or perpendicular bays, in place: an angle of 45-90 deg (half
    of them 90), 6-16 cars per 100 m, nose to the kerb with probability 0.5-0.9, the strips deepened to hold
    a 5.0 m x 1.9 m car at the angle plus 0.1-0.5 m (side views of parked cars, which parallel parking
    hardly shows)."""
    angle = 90.0 if rng.random() < 0.5 else round(float(rng.uniform(45, 90)), 1)
    a = np.radians(angle)
    sd["road"]["shoulder_width_m"] = round(float(5.0 * np.sin(a) + 1.9 * np.cos(a) + rng.uniform(0.1, 0.5)), 2)
    sd["road"]["street"] |= {"bay_angle_deg": angle, "parked_per_100m": round(float(rng.uniform(6, 16)), 1),
                             "facing_traffic_share": round(float(rng.uniform(0.5, 0.9)), 2)}


def random_dimensions(rng: np.random.Generator, vehicles: list[dict]) -> None:
    """Redraw the placed vehicles' footprints (m) in place from wider ranges than :func:`scenario_dict`'s:
    cars and vans 3.4-6.8 m x 1.5-2.2 m (over 5.5 m the mesh is a tall van), 25 % trucks 7.5-18 m x 2.3-2.6 m."""
    for v in vehicles:
        big = rng.random() < 0.25
        v["length_m"] = round(float(rng.uniform(7.5, 18.0) if big else rng.uniform(3.4, 6.8)), 2)
        v["width_m"] = round(float(rng.uniform(2.3, 2.6) if big else rng.uniform(1.5, 2.2)), 2)


def dress(sd: dict, seed: int, index: int, look: str, look_family: str, fleet: str) -> None:
    """Give a :func:`scenario_dict` scenario its look and fleet, in place, each from its own random stream
    (``[seed, index, 0x100C]``: the realistic look's seed; ``[seed, index, 0xF1EE]``: the placed vehicles'
    bodies), so the rest of the draw is unchanged. ``look`` ``simple`` and ``fleet`` ``none`` change nothing."""
    if look == "realistic":
        lrng = np.random.default_rng([seed, index, 0x100C])
        sd["render"] |= {"look": "realistic", "look_family": look_family, "look_seed": int(lrng.integers(0, 2**32))}
    if fleet == "mixed":
        from harness.world.fleet import draw_body

        frng = np.random.default_rng([seed, index, 0xF1EE])
        sd["traffic"]["fleet"] = "mixed"
        for v in sd["vehicles"]:
            v["body"], v["length_m"], v["width_m"] = draw_body(frng)


def visible_boxes(id_mask: np.ndarray, full_pixels: dict[int, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ids, boxes (K, 4) tight over visible pixels, continuous px; visibility (K,))."""
    labels = id_mask + 1
    counts = np.bincount(labels.ravel())
    ids, boxes, vis = [], [], []
    for lab, sl in enumerate(ndimage.find_objects(labels), start=1):
        if sl is None:
            continue
        vid = lab - 1
        ys, xs = sl
        ids.append(vid)
        boxes.append((xs.start - 0.5, ys.start - 0.5, xs.stop - 0.5, ys.stop - 0.5))
        vis.append(counts[lab] / max(full_pixels.get(vid, counts[lab]), 1.0))
    return np.array(ids, int), np.array(boxes, float).reshape(-1, 4), np.array(vis, float)


def amodal_in_view(ids: np.ndarray, boxes: np.ndarray, amodal: dict[int, np.ndarray], view: Fovea | None,
                   src: tuple[int, int]) -> np.ndarray:
    """The visible boxes ``boxes`` (view px) of vehicles ``ids`` replaced by their amodal boxes (image px) where
    the renderer drew them alone, shifted into ``view`` (None: the whole ``src`` = (w, h) image) and clipped."""
    x0, y0, w, h = (0, 0, *src) if view is None else (view.x0, view.y0, view.w, view.h)
    out = boxes.copy()
    for k, vid in enumerate(ids):
        a = amodal.get(int(vid))
        if a is not None:
            out[k] = box_ops.hull(box_ops.clip_to_image(np.asarray(a) - [x0, y0, x0, y0], w, h), boxes[k])
    return out


def fovea_of(scen) -> Fovea | None:
    """The detector's second-pass crop for this scenario's camera (default fovea parameters)."""
    from monorarp.detection.centernet import CenterNetDetector

    cam = scen.camera.model()
    kw = CenterNetDetector.FOVEA_DEFAULTS
    return Fovea.place(cam.width, cam.height, NET_W, NET_H, cam.cx, cam.horizon_row, kw["fovea_zoom"],
                       kw["fovea_below"])


def supersampled(scenario: dict, n: int):
    """The scenario with its camera at ``n`` x the resolution (same field of view and mounting)."""
    d = json.loads(json.dumps(scenario))
    d["camera"]["width"], d["camera"]["height"] = d["camera"]["width"] * n, d["camera"]["height"] * n
    return parse_scenario(d)


def fine_truth(renderer: Renderer, world, n: int) -> dict[int, np.ndarray]:
    """Vehicle id -> tight visible box (source px, continuous) from the id mask of ``renderer``
    (a camera at ``n`` x the source's resolution)."""
    ids, boxes, _ = visible_boxes(renderer.render(world).id_mask, {})
    return {int(v): (b + 0.5) / n - 0.5 for v, b in zip(ids, boxes)}


def generate(out: Path, n_scenarios: int, seed: int, frames_per_scenario: int, frame_stride: int,
             resolutions: tuple[tuple[int, int], ...], min_visibility: float, min_size: float,
             fovea: bool = False, keep_source: bool = False, truth_supersample: int = 1,
             conditions: float = 0.0, styled: float = 0.0, family: str = "train", dense: float = 0.0,
             look: str = "simple", look_family: str = "train", fleet: str = "none", street: float = 0.0,
             box_kind: str = "visible", bays: float = 0.0) -> None:
    """Render the set. With ``fovea`` every frame also gives a second image: the detector's fovea crop
    (:class:`monorarp.detection.fovea.Fovea`, stored as its own source image of the crop's size with
    the boxes of the vehicle pixels inside the crop; visibility still relative to the whole vehicle).
    With ``keep_source`` (one resolution only) the full-resolution frames are also stored, as
    ``source.npy`` (N, src_h, src_w, 3) uint8 BGR, with each image's camera in ``meta.json``: what the
    detector sees in the pipeline, for figures at the source resolution (:mod:`training.evaluate`).
    With ``truth_supersample`` N > 1 (needs ``keep_source``) the id masks are also rendered at N times
    the resolution, giving every stored box its continuous edges to 1/N px (``boxes_fine.npy``, rows
    aligned with ``boxes.npy``, source px; NaN where the vehicle has no pixel at the finer scale): the
    1x mask rounds each edge to a pixel boundary, +-0.5 px. A fraction ``styled`` of the scenarios gets an
    appearance style of ``family`` (``train`` or ``heldout``, :mod:`training.appearance`; ``none``: no style)
    and wider placed-vehicle dimensions. A fraction ``dense`` is made dense occluding traffic (:func:`densify`).
    ``look`` ``realistic`` renders every scenario with the realistic look of ``look_family`` (look seed from
    the scenario's own stream ``[seed, index, 0x100C]``). ``fleet`` ``mixed``: a mixed fleet in the traffic and
    the placed vehicles' bodies drawn from it (stream ``[seed, index, 0xF1EE]``). A fraction ``street`` is made
    urban streets with parked cars (:func:`streetify`, stream ``[seed, index, 0x57EE7]``; never dense); a fraction
    ``bays`` of those park in angled or perpendicular bays (:func:`add_bays`, stream ``[seed, index, 0xBA75]``).
    ``box_kind`` ``amodal``: each box is the vehicle's whole silhouette as if nothing hid it, clipped to the
    view (:mod:`harness.render.amodal`, KITTI's convention) instead of its visible pixels' box; the pixels,
    the visibility and which boxes are required stay the same."""
    if look == "realistic" and (conditions > 0 or styled > 0):
        raise SystemExit("--look realistic does not combine with --conditions or --appearance")
    if keep_source and (len(set(resolutions)) != 1 or fovea):
        raise SystemExit("--keep-source needs a single resolution and no --fovea")
    if truth_supersample > 1 and not keep_source:
        raise SystemExit("--truth-supersample needs --keep-source")
    if box_kind not in ("visible", "amodal"):
        raise SystemExit(f"--boxes {box_kind}: expected visible or amodal")
    if box_kind == "amodal" and truth_supersample > 1:
        raise SystemExit("--truth-supersample gives visible boxes only; leave it out with --boxes amodal")
    fine_rows: list[np.ndarray] = []
    out.mkdir(parents=True, exist_ok=True)
    images, rows, metas, sources = [], [], [], []
    t0 = time.time()
    skipped = 0
    for s in range(n_scenarios):
        rng = np.random.default_rng([seed, s])
        res = resolutions[int(rng.integers(len(resolutions)))]
        try:
            sd = scenario_dict(rng, s, seed, res)
            srng = np.random.default_rng([seed, s, 0x57EE7])
            is_street = srng.random() < street
            if is_street:
                streetify(srng, sd)
                brng = np.random.default_rng([seed, s, 0xBA75])
                if bays > 0 and brng.random() < bays:
                    add_bays(brng, sd)
            drng = np.random.default_rng([seed, s, 0xDE5])
            if drng.random() < dense and not is_street:
                densify(drng, sd)
            crng = np.random.default_rng([seed, s, 0xC0D])
            if crng.random() < conditions:
                sd["conditions"] = random_conditions(crng)
            arng = np.random.default_rng([seed, s, 0xA99])
            style = None
            if arng.random() < styled:   # dimensions first: both families then render the same scenes
                random_dimensions(arng, sd["vehicles"])
                samplers = {"train": appearance.sample_training, "heldout": appearance.sample_heldout}
                style = samplers[family](arng) if family in samplers else None
            dress(sd, seed, s, look, look_family, fleet)
            scen = parse_scenario(sd)
            frames = list(simulate(scen, frames_per_scenario * frame_stride))[::frame_stride]
        except ScenarioError:
            skipped += 1
            continue
        views = [(None, Letterbox.fit(res[0], res[1], NET_W, NET_H))]
        horizon = scen.camera.model().horizon_row
        fov = fovea_of(scen) if fovea else None
        if fov is not None:
            views.append((fov, Letterbox.fit(fov.w, fov.h, NET_W, NET_H)))
        with Renderer(scen) as r, (Renderer(supersampled(sd, truth_supersample)) if truth_supersample > 1
                                   else contextlib.nullcontext()) as r_fine:
            r.amodal = box_kind == "amodal"
            for wstate in frames:
                fr = r.render(wstate)
                image_full = fr.image if style is None else appearance.apply(style, fr.image, fr.id_mask, horizon)
                if r_fine is not None:
                    fine_by_id = fine_truth(r_fine, wstate, truth_supersample)
                for view, lb in views:
                    image, mask = image_full, fr.id_mask
                    if view is not None:
                        image, mask = view.cut(image), view.cut(mask)
                    ids, boxes, vis = visible_boxes(mask, fr.full_pixels)
                    if box_kind == "amodal":
                        boxes = amodal_in_view(ids, boxes, fr.amodal_boxes, view, res)
                    net = lb.to_dst(boxes)
                    big = ((net[:, 2] - net[:, 0]) >= min_size) & ((net[:, 3] - net[:, 1]) >= min_size)
                    required = (vis >= min_visibility) & big
                    i = len(images)
                    images.append(lb.apply(image))
                    if keep_source:
                        sources.append(image)
                    for vid, b, req in zip(ids, boxes, required):
                        rows.append((i, *b, 0.0 if req else 1.0))
                        if r_fine is not None:
                            fine_rows.append(fine_by_id.get(int(vid), np.full(4, np.nan)))
                    c = scen.camera
                    metas.append({"src_w": lb.src_w, "src_h": lb.src_h, "scenario": scen.name, "frame": wstate.frame,
                                  "hfov_deg": c.hfov_deg, "height_m": c.height_m, "pitch_deg": c.pitch_deg,
                                  "view": "full" if view is None else [view.x0, view.y0, view.w, view.h],
                                  "conditions": None if scen.conditions is None else scen.conditions.model_dump(),
                                  "style": None if style is None else style.to_dict(),
                                  "n_required": int(required.sum())}
                                 | ({"camera": scen.camera.model().to_dict()} if keep_source else {}))
        if (s + 1) % 10 == 0:
            print(f"{s + 1}/{n_scenarios} scenarios, {len(images)} images, {time.time() - t0:.0f}s", flush=True)
    np.save(out / "images.npy", np.stack(images))
    if keep_source:
        np.save(out / "source.npy", np.stack(sources))
    if truth_supersample > 1:
        np.save(out / "boxes_fine.npy", np.array(fine_rows, float).reshape(-1, 4))
    np.save(out / "boxes.npy", np.array(rows, float).reshape(-1, 6))
    (out / "meta.json").write_text(json.dumps({
        "net_input": [NET_W, NET_H], "seed": seed, "scenarios": n_scenarios, "skipped_scenarios": skipped,
        "frames_per_scenario": frames_per_scenario, "frame_stride": frame_stride,
        "resolutions": [list(r) for r in resolutions], "min_visibility": min_visibility,
        "min_size_net_px": min_size, "fovea": fovea, "conditions_fraction": conditions,
        "appearance_fraction": styled, "appearance_family": family, "dense_fraction": dense,
        "look": look, "look_family": look_family, "fleet": fleet}
        | ({"street_fraction": street} if street else {}) | ({"boxes": box_kind} if box_kind != "visible" else {})
        | ({"bays_fraction": bays} if bays else {})
        | {"images": metas}, indent=1))
    req = sum(m["n_required"] for m in metas)
    print(f"wrote {len(images)} images, {req} required boxes, {len(rows) - req} ignored to {out} "
          f"({skipped} scenarios skipped) in {time.time() - t0:.0f}s", flush=True)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--scenarios", type=int, default=300)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--frames", type=int, default=10, help="frames rendered per scenario")
    ap.add_argument("--stride", type=int, default=20, help="simulation frames between rendered frames (15 fps)")
    ap.add_argument("--resolutions", type=str, default=None, help="e.g. 640x360,1280x720")
    ap.add_argument("--min-visibility", type=float, default=0.3)
    ap.add_argument("--min-size", type=float, default=3.0, help="px at the net's 320x192 scale")
    ap.add_argument("--fovea", action="store_true", help="also store each frame's fovea crop (second pass)")
    ap.add_argument("--truth-supersample", type=int, default=1, metavar="N",
                    help="with --keep-source: also store boxes from id masks rendered at N x (boxes_fine.npy)")
    ap.add_argument("--keep-source", action="store_true",
                    help="also store the full-resolution frames (source.npy) and cameras (one resolution only)")
    ap.add_argument("--conditions", type=float, default=0.0, metavar="P",
                    help="fraction of scenarios with random light/weather/lens conditions (default 0)")
    ap.add_argument("--appearance", type=float, default=0.0, metavar="P",
                    help="fraction of scenarios with a random appearance style and wider vehicle sizes (default 0)")
    ap.add_argument("--appearance-family", choices=("train", "heldout", "none"), default="train",
                    help="style family: train, the held-out family (validation only), or none (the same "
                         "scenes and vehicle sizes, unstyled)")
    ap.add_argument("--dense", type=float, default=0.0, metavar="P",
                    help="fraction of scenarios made dense occluding traffic (densify; default 0)")
    ap.add_argument("--look", choices=("simple", "realistic"), default="simple",
                    help="render look of every scenario (default simple; realistic: harness.render.look)")
    ap.add_argument("--look-family", choices=("train", "heldout"), default="train",
                    help="randomisation family of the realistic look (heldout: validation only)")
    ap.add_argument("--fleet", choices=("none", "mixed"), default="none",
                    help="traffic fleet: none (the simulator's 5 x 2 m cars; placed sizes as drawn) or mixed "
                         "(harness.world.fleet body types for traffic and placed vehicles)")
    ap.add_argument("--street", type=float, default=0.0, metavar="P",
                    help="fraction of scenarios made urban streets with parked cars (streetify; default 0)")
    ap.add_argument("--street-bays", type=float, default=0.0, metavar="P",
                    help="fraction of the street scenarios parked in angled or perpendicular bays (add_bays; "
                         "default 0)")
    ap.add_argument("--boxes", choices=("visible", "amodal"), default="visible",
                    help="label boxes: the visible pixels' (default) or amodal: the whole vehicle as if nothing "
                         "hid it, clipped to the image (KITTI's convention)")
    a = ap.parse_args(argv)
    res = TRAIN_RESOLUTIONS if a.resolutions is None else tuple(
        tuple(int(v) for v in r.split("x")) for r in a.resolutions.split(","))
    if not 0.0 <= a.conditions <= 1.0:
        ap.error("--conditions must be a fraction in [0, 1]")
    if not 0.0 <= a.dense <= 1.0:
        ap.error("--dense must be a fraction in [0, 1]")
    if not 0.0 <= a.appearance <= 1.0:
        ap.error("--appearance must be a fraction in [0, 1]")
    if not 0.0 <= a.street <= 1.0:
        ap.error("--street must be a fraction in [0, 1]")
    if not 0.0 <= a.street_bays <= 1.0:
        ap.error("--street-bays must be a fraction in [0, 1]")
    generate(a.out, a.scenarios, a.seed, a.frames, a.stride, res, a.min_visibility, a.min_size, a.fovea,
             a.keep_source, a.truth_supersample, a.conditions, a.appearance, a.appearance_family, a.dense,
             a.look, a.look_family, a.fleet, a.street, a.boxes, a.street_bays)


if __name__ == "__main__":
    main()
