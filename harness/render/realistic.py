"""The scene of the realistic look (:mod:`harness.render.look`): what the renderer adds or draws
differently when ``render.look`` is ``realistic``.

- the road's surfaces textured (:mod:`~harness.render.textures`), their shading in the vertex colours;
- the roadside (:mod:`~harness.render.roadside`): occluders (rails, median, trees, bushes, poles,
  signs, gantries; on a street kerbs and the frontage of :mod:`~harness.render.street`), the far set
  (buildings, hills) and the shadows the occluders cast on the ground;
- a sky dome (:mod:`~harness.render.sky`) kept centred on the camera, in :data:`DOME_SECTORS` nodes (and the
  far set in :data:`FAR_CELL_M` cells) so the renderer can skip those outside the view;
- detailed vehicles (:func:`harness.render.meshes.vehicle_faces_detailed`) shaded by
  :func:`harness.render.materials.shade_realistic`, each with its sun shadow
  (:mod:`~harness.render.shadows`) as a separate, alpha-blended node;
- the sensor (:mod:`~harness.render.camera_sensor`) on the finished colour image.

The truth stays exact: shadows, the dome, the road and the far set are not in the id pass; the
occluders are, with the code :data:`OCCLUDER_CODE`, so a vehicle behind a tree or a rail is hidden
in the id mask as it is in the image (the renderer turns the code into -1, background, after
using it to decide which vehicles need an unoccluded sub-window render for their visibility).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pyrender

from harness.render import camera_sensor, materials, meshes, scenery, shadows, sky, textures
from harness.render.look import LookParams, sample_look, sun_direction_w
from harness.render.road import road_surface_uv
from harness.world.road_plan import RoadPlan
from harness.world.road_profile import RoadProfile
from harness.world.scenario import Scenario
from harness.world.vehicles import vehicle_height

#: The id-pass code of every roadside occluder (vehicle codes are id + 1, far below it).
OCCLUDER_CODE = 0xFFFFFE
CELL_M = 100.0
"""The roadside is cut into square cells this wide (m) in the ground plane, one node each, so that a frame
draws only the cells in front of the camera and within :data:`DRAW_DISTANCE_M` (llvmpipe pays per triangle)."""
DOME_AZIMUTHS, DOME_RINGS = 72, 16     # the sky dome's tessellation: smooth gradient, clouds of a few degrees
DOME_SECTORS = 12          # the dome is drawn as this many azimuth sectors (nodes), those outside the view skipped
FAR_CELL_M = 1000.0        # the far set (buildings, hills) in cells this wide (m), those outside the view skipped
DRAW_DISTANCE_M = 900.0
LOD_FAR_M, LOD_NEAR_M = 65.0, 55.0
"""A detailed vehicle farther than ``LOD_FAR_M`` from the camera is drawn with the simple look's mesh (about a
tenth of the triangles) in its realistic paint and materials, and detailed again nearer than ``LOD_NEAR_M``
(hysteresis: no flicker at the boundary). At 60 m a car is about 20 px wide at a focal length of 640 px; the
id mask is always that of the mesh drawn, so the truth stays exact."""
"""Occluder and shadow cells farther than this (m, cell centre) are not drawn; beyond it a 10 m tree is under
10 px tall at a focal length of 900 px. The far set (buildings, hills) is always drawn."""


def flat_mesh(triangles: np.ndarray, colors: np.ndarray, material: pyrender.Material) -> pyrender.Mesh:
    """(F, 3, 3) triangles with colours (F, 3) per face or (F, 3, 3) per vertex, 0..1 (an optional
    fourth channel: alpha) -> one-primitive pyrender mesh."""
    colors = np.asarray(colors, dtype=float)
    per_vertex = colors if colors.ndim == 3 else np.repeat(colors[:, None, :], 3, axis=1)
    if per_vertex.shape[-1] == 3:
        per_vertex = np.concatenate([per_vertex, np.ones((*per_vertex.shape[:2], 1))], axis=-1)
    prim = pyrender.Primitive(positions=np.asarray(triangles, np.float32).reshape(-1, 3),
                              color_0=per_vertex.reshape(-1, 4).astype(np.float32),
                              material=material, mode=pyrender.constants.GLTF.TRIANGLES)
    return pyrender.Mesh([prim])


def face_normals(triangles: np.ndarray) -> np.ndarray:
    """(F, 3) unit normals of counter-clockwise (F, 3, 3) triangles."""
    n = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


#: Paint of the realistic look's vehicles (sRGB) with the share of each in the European fleet (white,
#: black, grey and silver dominate; yellow, orange and green are 1-2 % each): a flat palette makes one
#: car in seven yellow or orange, colours a COCO-trained detector associates with buses and taxis.
FLEET_PAINTS = np.array([
    [228, 228, 225], [22, 22, 25], [105, 108, 112], [165, 168, 172], [150, 22, 28], [28, 55, 120],
    [18, 28, 55], [120, 100, 80], [30, 70, 45], [215, 170, 30], [200, 90, 25], [95, 20, 32]], dtype=float)
FLEET_SHARES = np.array([0.24, 0.19, 0.16, 0.12, 0.08, 0.07, 0.04, 0.03, 0.02, 0.015, 0.015, 0.02])


def fleet_color(look_seed: int, vehicle_id: int) -> tuple[int, int, int]:
    """A vehicle's paint drawn from :data:`FLEET_PAINTS` by fleet share (deterministic per look and id)."""
    rng = np.random.default_rng([int(look_seed) & 0xFFFFFFFF, int(vehicle_id) & 0xFFFFFFFF, 0xC010])
    base = FLEET_PAINTS[rng.choice(len(FLEET_PAINTS), p=FLEET_SHARES / FLEET_SHARES.sum())]
    rgb = np.clip(base * rng.uniform(0.92, 1.08) + rng.normal(0.0, 5.0, 3), 0, 255)
    return tuple(int(c) for c in np.round(rgb))


def simple_materials(albedo: np.ndarray) -> np.ndarray:
    """(F,) material tags of a simple-look mesh, from its fixed part colours (paint: everything else)."""
    tags = np.full(len(albedo), int(materials.Material.PAINT), dtype=np.int8)
    for colour, tag in ((meshes.GLASS, materials.Material.GLASS), (meshes.TYRE, materials.Material.TYRE),
                        (meshes.RIM, materials.Material.RIM), (meshes.TAIL_LIGHT, materials.Material.LIGHT),
                        (meshes.TRIM, materials.Material.TRIM)):
        tags[np.all(albedo == np.asarray(colour, dtype=float), axis=1)] = int(tag)
    return tags


def _cells(triangles: np.ndarray, size: float = CELL_M) -> list[tuple[np.ndarray, np.ndarray]]:
    """(face mask, cell centre XY) of every ``size`` (m) ground cell holding a face of ``triangles`` (its centroid)."""
    cell = np.floor(triangles[:, :, :2].mean(axis=1) / size).astype(np.int64)
    keys, inverse = np.unique(cell, axis=0, return_inverse=True)
    return [(inverse.ravel() == k, (keys[k] + 0.5) * size) for k in range(len(keys))]


def _sectors(triangles: np.ndarray, n: int) -> list[np.ndarray]:
    """Face masks of the ``n`` azimuth sectors (about the origin, from +X) holding the faces' centroids."""
    c = triangles.mean(axis=1)
    k = np.floor(np.mod(np.arctan2(c[:, 1], c[:, 0]), 2 * np.pi) / (2 * np.pi / n)).astype(int) % n
    return [k == i for i in range(n) if (k == i).any()]


def look_of(scenario: Scenario) -> LookParams:
    """The realistic look ``scenario`` asks for (its ``look_seed``, else its seed, in ``look_family``)."""
    r = scenario.render
    return sample_look(scenario.seed if r.look_seed is None else r.look_seed, r.look_family)


@dataclass
class VehicleParts:
    """A detailed vehicle in its model frame, before shading."""

    triangles: np.ndarray
    normals: np.ndarray
    albedo: np.ndarray
    material: np.ndarray
    height: float


class RealisticScene:
    """The realistic look's static nodes in ``scene`` and its per-vehicle meshes and sensor."""

    def __init__(self, scene: pyrender.Scene, scenario: Scenario, profile: RoadProfile | None,
                 plan: RoadPlan | None, add_mesh) -> None:
        self.look = look = look_of(scenario)
        self.sun_w = sun_direction_w(look.sun)
        self._seed = scenario.seed
        self._material = pyrender.MetallicRoughnessMaterial(baseColorFactor=(1.0, 1.0, 1.0, 1.0))
        self._shadow_material = pyrender.MetallicRoughnessMaterial(baseColorFactor=(1.0, 1.0, 1.0, 1.0),
                                                                   alphaMode="BLEND")
        self._ground_srgb = look.surface.asphalt_srgb
        self.shadow_alpha = shadows.shadow_alpha(look.sun.ambient, look.sun.intensity,
                                                 math.radians(look.sun.elevation_deg), look.sun.shadow_strength)
        road = scenario.road
        texs = textures.road_textures(look.surface, road.lane_width_m)
        tiling = textures.road_tiling(look.surface)
        if road.street is not None:
            texs["pavement"] = textures.pavement_texture(look.surface, look.street, tiling.pavement_m)
        for kind, (tri, uv) in road_surface_uv(road, profile, plan, tiling).items():
            albedo = textures.mean_srgb(texs[kind])
            shaded = self._shade_matte(np.tile(albedo, (len(tri), 1)), face_normals(tri))
            add_mesh(scene, textures.textured_mesh(tri, uv, textures.vertex_rgb(shaded, albedo), texs[kind]))
        geo = scenery.roadside_geometry(road, profile, plan, look.roadside, self.sun_w, look.street)
        self.occluder_nodes: list[pyrender.Node] = []
        self._cells: list[tuple[pyrender.Node, np.ndarray]] = []     # (node, cell centre XY) of culled nodes
        self._centres: np.ndarray | None = None                       # (C, 2) those centres, stacked
        occ = geo.occluders
        if len(occ):
            colours = self._shade_matte(occ.albedo, occ.normals)
            for keep, centre in _cells(occ.triangles):
                node = add_mesh(scene, flat_mesh(occ.triangles[keep], colours[keep], self._material))
                self.occluder_nodes.append(node)
                self._cells.append((node, centre))
        self.far_nodes: list[pyrender.Node] = []     # the far set in FAR_CELL_M cells, always drawn (if in view)
        if len(geo.far):
            colours = self._shade_matte(geo.far.albedo, geo.far.normals)
            for keep, _ in _cells(geo.far.triangles, FAR_CELL_M):
                self.far_nodes.append(add_mesh(scene, flat_mesh(geo.far.triangles[keep], colours[keep],
                                                                self._material)))
        for keep, centre in _cells(geo.shadows) if len(geo.shadows) else ():
            self._cells.append((add_mesh(scene, self._shadow_mesh(geo.shadows[keep])), centre))
        dome_tri, dome_rgb = sky.sky_dome(look.sky, self.sun_w, n_azimuth=DOME_AZIMUTHS, n_elevation=DOME_RINGS)
        self.dome_nodes = [add_mesh(scene, flat_mesh(dome_tri[keep], dome_rgb[keep], self._material))
                           for keep in _sectors(dome_tri, DOME_SECTORS)]

    def _shade_matte(self, albedo: np.ndarray, normals: np.ndarray) -> np.ndarray:
        return materials.shade_matte(albedo, normals, self.sun_w, self.look.sun, self.look.sky,
                                     ground_srgb=self._ground_srgb)

    def _shadow_mesh(self, triangles: np.ndarray) -> pyrender.Mesh:
        rgba = np.zeros((len(triangles), 4))
        rgba[:, 3] = self.shadow_alpha
        return flat_mesh(triangles, rgba, self._shadow_material)

    @property
    def sky_srgb(self) -> tuple[float, float, float]:
        """Background colour (sRGB 0..1) wherever the dome does not reach: its horizon colour."""
        return tuple(c / 255.0 for c in self.look.sky.horizon_srgb)

    # ------------------------------------------------------------------ vehicles
    def vehicle_parts(self, length: float, width: float, vehicle_id: int, body: str | None = None) -> VehicleParts:
        """The detailed vehicle of ``vehicle_id`` (body type ``body``, else its style by id; paint by fleet
        share, metallic for :func:`materials.is_metallic` of it)."""
        tri, normals, albedo, material = meshes.vehicle_faces_detailed(
            length, width, fleet_color(self.look.seed, vehicle_id), self.look.vehicle.dirt, seed=int(vehicle_id),
            body=body)
        material = materials.metallic_paint(material, materials.is_metallic(self.look.seed, vehicle_id, body))
        return VehicleParts(tri, normals, albedo, material, vehicle_height(length, width, body))

    def vehicle_mesh(self, parts: VehicleParts, light_model: np.ndarray) -> pyrender.Mesh:
        """The vehicle's mesh shaded for light travelling along ``light_model`` (its model frame)."""
        colours = materials.shade_realistic(parts.albedo, parts.normals, parts.material, light_model,
                                            self.look.sun, self.look.sky, self.look.vehicle.gloss,
                                            ground_srgb=self._ground_srgb)
        return flat_mesh(parts.triangles, colours, self._material)

    def vehicle_shadow(self, length: float, width: float, height: float,
                       light_model: np.ndarray) -> pyrender.Mesh | None:
        """The vehicle's cast shadow (model frame), or None when the sun casts none."""
        tri = shadows.cast_shadow(length, width, height, light_model)
        return self._shadow_mesh(tri) if len(tri) else None

    def far_parts(self, length: float, width: float, vehicle_id: int, body: str | None = None) -> VehicleParts:
        """The simple look's mesh of ``vehicle_id`` with the realistic paint and material tags (the far LOD)."""
        tri, normals, albedo = meshes.vehicle_faces(length, width, fleet_color(self.look.seed, vehicle_id), body=body)
        material = materials.metallic_paint(simple_materials(albedo),
                                            materials.is_metallic(self.look.seed, vehicle_id, body))
        return VehicleParts(tri, normals, albedo, material, vehicle_height(length, width, body))

    # -------------------------------------------------------------------- frames
    def follow_camera(self, scene: pyrender.Scene, camera_pose: np.ndarray) -> None:
        """Centre the sky dome on the camera; draw only the roadside cells in front of it and in range (and
        every far-set cell and dome sector: the renderer hides those of them outside the view)."""
        pose = np.eye(4)
        pose[:3, 3] = camera_pose[:3, 3]
        for node in self.dome_nodes:
            scene.set_pose(node, pose)
        for node in self.far_nodes + self.dome_nodes:
            node.mesh.is_visible = True
        eye, forward = camera_pose[:2, 3], -camera_pose[:2, 2]          # OpenGL camera: it looks along -Z
        forward = forward / max(float(np.linalg.norm(forward)), 1e-9)
        half_diagonal = CELL_M / math.sqrt(2.0)
        if not self._cells:
            return
        if self._centres is None:
            self._centres = np.array([centre for _, centre in self._cells], dtype=float)
        d = self._centres - eye
        show = (np.hypot(d[:, 0], d[:, 1]) <= DRAW_DISTANCE_M + half_diagonal) & (d @ forward >= -half_diagonal)
        for (node, _), s in zip(self._cells, show.tolist()):
            node.mesh.is_visible = s

    def sensor(self, image: np.ndarray, frame: int) -> np.ndarray:
        """The look's camera applied to the finished colour image (BGR uint8)."""
        return camera_sensor.apply_camera(image, self.look.sensor, self._seed, int(frame))
