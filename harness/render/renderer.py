"""The pyrender scene of one scenario: static road, per-vehicle meshes, camera, light.

Static geometry (road surfaces and all markings) is built once as four merged
meshes; per frame only vehicle node poses (nodes added/removed when the vehicle
set changes) and the camera pose are updated. Lighting is a directional light
(``render.light_direction``, ``light_intensity``) plus ambient, evaluated per
face and baked into vertex colours (:mod:`harness.render.shading`): the road
once, a vehicle again only when its heading moves into another 1-degree bin.

Two passes per frame, drawn by :mod:`harness.render.passes` with pyrender's shaders: a
colour pass (FLAT shader, 4x MSAA, no shadows) and an exact id pass (SEG shader,
single-sampled, so each pixel holds the vehicle covering its centre; ids colour-encoded
as id + 1 in 24 bits). The ego is not drawn. :mod:`harness.render.visibility` explains
the extra sub-window id renders behind ``visibility``.

A scenario's ``conditions:`` block (time of day, fog, rain, lens; :mod:`harness.render.effects`)
changes the scene lighting and, through the colour pass's depth buffer (read only then), adds
image-space effects; without it (or with a neutral one) nothing of that runs.

Realistic look: roadside cells, far-set cells, dome sectors and vehicle shadows wholly outside the
view are not drawn, and the id pass is drawn only in the rectangle around the drawn vehicles' boxes
(both leave every pixel and the truth as they were; ``tests/test_render_culling.py``).

A camera with lens distortion draws both passes on a wider pinhole canvas and warps them onto the
distorted image (:mod:`harness.render.distortion`); a pinhole camera runs none of that.

pyrender's ``IntrinsicsCamera`` puts pixel centres at half-integers of its
cx/cy (OpenGL window convention); OpenCV's are at integers, so cx/cy are passed
shifted by +0.5 (checked by the tests against ``cv2.projectPoints``).
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import math
import os
from dataclasses import dataclass, field

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np  # noqa: E402
import pyrender  # noqa: E402
from OpenGL import GL  # noqa: E402

from harness.render import amodal as amodal_mod  # noqa: E402
from harness.render import effects, meshes, passes, road, shading, visibility  # noqa: E402
from harness.render import realistic  # noqa: E402
from harness.render.realistic import OCCLUDER_CODE, RealisticScene, VehicleParts, flat_mesh  # noqa: E402
from harness.world import geometry  # noqa: E402
from harness.world.vehicles import vehicle_height  # noqa: E402
from harness.render.sensor import apply_sensor  # noqa: E402
from harness.render.distortion import lens_warp  # noqa: E402
from harness.world.scenario import Scenario  # noqa: E402
from harness.world.road import road_plan, road_profile  # noqa: E402
from harness.world.state import VehicleState, WorldState  # noqa: E402
from monorarp.core.camera import CameraModel  # noqa: E402

ZNEAR_M = 0.05
ZFAR_M = 6000.0
PIXEL_CENTRE_SHIFT = 0.5
HEADING_BIN_RAD = math.radians(1.0)
ANISOTROPY = 1.0          # realistic look: the road's textures at grazing angles
_live_renderers = 0   # pyrender's EGL teardown terminates the shared display: only the last may do it


@dataclass
class RenderedFrame:
    """One rendered frame.

    ``camera``: with a ``camera_motion:`` block, the true (moved) camera the frame was
    rendered with; None for a camera that never moves on its mount.
    ``image``: (H, W, 3) uint8 BGR after optional noise/blur. ``id_mask``: (H, W)
    int32 vehicle id per pixel (-1 elsewhere), noise-free. ``full_pixels``: for
    each id in the mask, the pixels the vehicle would cover with nothing in front
    of it and no image border (the denominator of ``visibility``).
    """

    frame: int
    image: np.ndarray
    id_mask: np.ndarray
    full_pixels: dict[int, float] = field(default_factory=dict)
    camera: CameraModel | None = None    # the frame's true camera when the scenario moves it (camera_motion)
    #: with ``Renderer.amodal``: id -> amodal box (image px, clipped; :mod:`harness.render.amodal`) of each
    #: vehicle drawn alone; a visible vehicle not in it is unhidden, so its visible box is its amodal box
    amodal_boxes: dict[int, np.ndarray] = field(default_factory=dict)


def _seg_colour(code: int) -> tuple[int, int, int]:
    return code & 0xFF, (code >> 8) & 0xFF, (code >> 16) & 0xFF


_draw_orders = itertools.count()


def _add_mesh(scene: pyrender.Scene, mesh: pyrender.Mesh, pose: np.ndarray | None = None) -> pyrender.Node:
    """``scene.add`` recording the node's insertion order (the draw-order tie-break, :mod:`~harness.render.passes`)."""
    node = scene.add(mesh, pose=pose)
    node._draw_order = next(_draw_orders)
    return node


def _set_mesh(scene: pyrender.Scene, node: pyrender.Node, mesh: pyrender.Mesh) -> None:
    """Give ``node`` a new mesh in place (its pose and draw order kept), keeping pyrender's object -> nodes
    index true: ``node.mesh = mesh`` alone leaves the old mesh indexed, and ``scene.remove_node`` of the node
    later fails (a vehicle that leaves the frame after a level-of-detail or heading-bin swap)."""
    index = scene._obj_to_nodes
    old = index.get(node.mesh)
    if old is not None:
        old.discard(node)
        if not old:
            index.pop(node.mesh)
    node.mesh = mesh
    index.setdefault(mesh, set()).add(node)


def _release(pr: pyrender.OffscreenRenderer) -> None:
    """Free ``pr``'s GL context; the shared EGL display is terminated only by the last live renderer.

    pyrender's own ``delete`` does the same and then a full ``gc.collect()`` (0.3-0.7 s with the
    simulator loaded), which nothing here needs.
    """
    global _live_renderers
    _live_renderers -= 1
    platform = pr._platform
    platform.make_current()
    pr._renderer.delete()
    if _live_renderers > 0 and getattr(platform, "_egl_display", None) is not None:
        from OpenGL import EGL

        EGL.eglMakeCurrent(platform._egl_display, EGL.EGL_NO_SURFACE, EGL.EGL_NO_SURFACE, EGL.EGL_NO_CONTEXT)
        EGL.eglDestroyContext(platform._egl_display, platform._egl_context)
        platform._egl_context = platform._egl_display = None
    else:
        platform.delete_context()
    pr._renderer = pr._platform = None


@functools.cache
def gl_identity() -> str:
    """``vendor | renderer | version`` of the OpenGL implementation this process renders with.

    E.g. ``Mesa/X.org | llvmpipe (LLVM 15.0.6, 256 bits) | 4.5 (Core Profile) Mesa 22.3.6`` on this machine;
    a GPU's EGL driver names the GPU. Read once per process from a 1x1 offscreen context
    (about 0.1 s). Part of the frame-cache key: another rasteriser may colour edge pixels differently.
    """
    global _live_renderers
    pr = pyrender.OffscreenRenderer(1, 1)
    _live_renderers += 1
    try:
        pr._platform.make_current()
        parts = [GL.glGetString(name) for name in (GL.GL_VENDOR, GL.GL_RENDERER, GL.GL_VERSION)]
        return " | ".join(p.decode("utf-8", "replace") if isinstance(p, bytes) else str(p) for p in parts)
    finally:
        _release(pr)


def _mesh_bounds(mesh: pyrender.Mesh) -> np.ndarray:
    """(2, 3) axis-aligned bounds [min, max] of an un-instanced mesh's vertices (model frame), cached on the mesh
    (pyrender's own ``Mesh.bounds`` uses ``np.infty``, gone in NumPy 2)."""
    bounds = mesh.__dict__.get("_render_bounds")
    if bounds is None:
        if any(p.poses is not None for p in mesh.primitives):
            raise ValueError("instanced primitives have no single model-frame box")
        pts = np.concatenate([p.positions for p in mesh.primitives])
        bounds = mesh._render_bounds = np.stack([pts.min(axis=0), pts.max(axis=0)]).astype(float)
    return bounds


@dataclass
class _Vehicle:
    node: pyrender.Node
    dims: tuple[float, float]
    triangles: np.ndarray     # (F, 3, 3) model frame
    normals: np.ndarray       # (F, 3) model frame
    albedo: np.ndarray        # (F, 3) sRGB 0..255
    heading_bin: int
    parts: VehicleParts | None = None          # realistic look: the detailed mesh
    shadow_node: pyrender.Node | None = None   # realistic look: its sun shadow
    far: bool = False                          # realistic look: drawn with the far level of detail
    body: str | None = None                    # the vehicle's body type (harness.world.vehicles)


class Renderer:
    """Renders :class:`WorldState` s of one scenario as seen by its dashcam."""

    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self.camera: CameraModel = scenario.camera.model()      # the nominal calibration
        self.frame_camera: CameraModel = self.camera            # the true camera of the current frame
        self._motion = None
        if scenario.camera_motion is not None:
            from harness.world.camera_motion import CameraMotionModel

            self._motion = CameraMotionModel(scenario.camera_motion, self.camera, scenario.fps, scenario.seed)
        self._motion_frame: int | None = None
        #: True: :meth:`render` also fills ``RenderedFrame.amodal_boxes`` (for training labels; pixels unchanged)
        self.amodal = False
        opts = scenario.render
        self._palette_seed = opts.palette_seed
        self._light_w = np.asarray(opts.light_direction, dtype=float)
        self._intensity = opts.light_intensity
        self._noise_std, self._blur_px, self._seed = opts.noise_std, opts.blur_px, scenario.seed
        # conditions: None keeps the default path (no depth read, no effects) exactly as without the block
        self._lighting = None if effects.is_neutral(scenario.conditions) else effects.scene_lighting(scenario)
        sky = shading.SKY_RGB if self._lighting is None else self._lighting.sky_srgb
        if self._lighting is not None:
            self._light_w, self._intensity = np.asarray(self._lighting.light_w, dtype=float), self._lighting.intensity
        self._scene = pyrender.Scene(bg_color=(*sky, 1.0), ambient_light=(0.0, 0.0, 0.0))
        self._material = pyrender.MetallicRoughnessMaterial(baseColorFactor=(1.0, 1.0, 1.0, 1.0))
        self._profile = road_profile(scenario.road.profile, scenario.camera.forward_offset_m)
        self._plan = road_plan(scenario.road.curves, scenario.camera.forward_offset_m)
        self._real: RealisticScene | None = None
        if opts.look == "realistic":     # the look's sun replaces render.light_* (a daylight look)
            self._real = RealisticScene(self._scene, scenario, self._profile, self._plan, _add_mesh)
            self._light_w = self._real.sun_w
            self._scene.bg_color = np.array([*self._real.sky_srgb, 1.0])
        else:
            for tm in road.road_trimeshes(scenario.road, self._profile, self._plan).values():
                colors = self._shade(tm.visual.face_colors[:, :3], tm.face_normals, self._light_w)
                _add_mesh(self._scene, flat_mesh(tm.vertices[tm.faces], colors, self._material))
        self._lens = lens_warp(self.camera)   # a distorted lens: passes on a wider pinhole canvas, then warped
        c = self._drawn(self.camera)
        self._cam = pyrender.IntrinsicsCamera(c.fx, c.fy, c.cx + PIXEL_CENTRE_SHIFT, c.cy + PIXEL_CENTRE_SHIFT,
                                              znear=ZNEAR_M, zfar=ZFAR_M)
        self._cam_node = self._scene.add(self._cam, pose=np.eye(4))
        self._vehicles: dict[int, _Vehicle] = {}
        self._static_corners: dict[pyrender.Node, np.ndarray] = {}    # realistic look: static nodes' world boxes
        global _live_renderers
        self._pr: pyrender.OffscreenRenderer | None = pyrender.OffscreenRenderer(c.width, c.height)
        _live_renderers += 1
        self._passes = passes.Passes(self._pr, max_anisotropy=1.0 if self._real is None else ANISOTROPY)
        self._ray_factor = None if self._lighting is None else effects.ray_length_factor(c)
        if self._lens is not None and self._ray_factor is not None:
            self._ray_factor = self._lens.linear(self._ray_factor)

    def _drawn(self, camera: CameraModel) -> CameraModel:
        """The pinhole camera the passes are drawn with: ``camera`` itself, or its lens's canvas
        (:mod:`harness.render.distortion`)."""
        return camera if self._lens is None else self._lens.canvas(camera)

    def _shade(self, albedo: np.ndarray, normals: np.ndarray, light: np.ndarray) -> np.ndarray:
        """Face colours (0..1 sRGB) under this scenario's light (and time of day, with ``conditions``)."""
        if self._lighting is None:
            return shading.shade(albedo, normals, light, self._intensity)
        return effects.shade_faces(albedo, normals, light, self._lighting)

    # ----------------------------------------------------------------- lifecycle
    def close(self) -> None:
        """Free the GL context (other live renderers keep theirs)."""
        if self._pr is None:
            return
        with self._gl():
            self._passes.delete()
        _release(self._pr)
        self._pr = None

    def __enter__(self) -> "Renderer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------- scene
    def _vehicle_mesh(self, entry: _Vehicle) -> pyrender.Mesh:
        # Light into the model frame: the model is rotated by -heading about Z in W.
        light_model = self._light_model(entry)
        if entry.parts is not None:
            return self._real.vehicle_mesh(entry.parts, light_model)
        colors = self._shade(entry.albedo, entry.normals, light_model)
        return flat_mesh(entry.triangles, colors, self._material)

    def _light_model(self, entry: _Vehicle) -> np.ndarray:
        return shading.rotate_z(self._light_w, entry.heading_bin * HEADING_BIN_RAD)

    def _set_shadow(self, entry: _Vehicle, pose: np.ndarray) -> None:
        """Realistic look: (re)make ``entry``'s shadow node for its heading bin, at ``pose``."""
        if entry.shadow_node is not None:
            self._scene.remove_node(entry.shadow_node)
            entry.shadow_node = None
        mesh = self._real.vehicle_shadow(*entry.dims, entry.parts.height, self._light_model(entry))
        if mesh is not None:
            entry.shadow_node = _add_mesh(self._scene, mesh, pose=pose)

    def _sync_vehicles(self, vehicles: tuple[VehicleState, ...], eye: np.ndarray) -> list[pyrender.Node]:
        """Add, update and remove the vehicles' nodes; a new realistic vehicle is built directly in the level of
        detail its distance from ``eye`` (W, m) asks for."""
        present = {v.id for v in vehicles}
        for vid in [k for k in self._vehicles if k not in present]:
            gone = self._vehicles.pop(vid)
            self._scene.remove_node(gone.node)
            if gone.shadow_node is not None:
                self._scene.remove_node(gone.shadow_node)
        nodes = []
        for v in vehicles:
            dims = (v.length, v.width)
            yaw = v.heading if self._plan is None else v.heading + float(self._plan.theta(v.x))
            hbin = int(round(yaw / HEADING_BIN_RAD))
            entry = self._vehicles.get(v.id)
            pose = geometry.vehicle_pose_world(v, self._profile, self._plan)
            if entry is None or entry.dims != dims or entry.body != v.body:
                if entry is not None:
                    self._scene.remove_node(entry.node)
                    if entry.shadow_node is not None:
                        self._scene.remove_node(entry.shadow_node)
                if self._real is None:
                    color = meshes.vehicle_color(self._palette_seed, v.id)
                    entry = _Vehicle(None, dims, *meshes.vehicle_faces(v.length, v.width, color, body=v.body), hbin,
                                     body=v.body)
                else:
                    far = float(np.linalg.norm(pose[:3, 3] - eye)) > realistic.LOD_FAR_M
                    make = self._real.far_parts if far else self._real.vehicle_parts
                    parts = make(v.length, v.width, v.id, v.body)
                    entry = _Vehicle(None, dims, parts.triangles, parts.normals, parts.albedo, hbin, parts, far=far,
                                     body=v.body)
                    self._set_shadow(entry, pose)
                entry.node = _add_mesh(self._scene, self._vehicle_mesh(entry), pose=pose)
                self._vehicles[v.id] = entry
            else:
                if entry.heading_bin != hbin:
                    entry.heading_bin = hbin
                    _set_mesh(self._scene, entry.node, self._vehicle_mesh(entry))
                    if entry.parts is not None:
                        self._set_shadow(entry, pose)
                self._scene.set_pose(entry.node, pose)
                if entry.shadow_node is not None:
                    self._scene.set_pose(entry.shadow_node, pose)
            nodes.append(entry.node)
        return nodes

    def _level_of_detail(self, vehicles: tuple[VehicleState, ...], eye: np.ndarray) -> None:
        """Realistic look: swap each vehicle's mesh between its detailed and far forms by its distance."""
        for v in vehicles:
            entry = self._vehicles[v.id]
            d = float(np.linalg.norm(self._scene.get_pose(entry.node)[:3, 3] - eye))
            far = d > realistic.LOD_FAR_M if not entry.far else d >= realistic.LOD_NEAR_M
            if far != entry.far:
                entry.far = far
                make = self._real.far_parts if far else self._real.vehicle_parts
                entry.parts = make(v.length, v.width, v.id, v.body)
                entry.triangles, entry.normals, entry.albedo = entry.parts.triangles, entry.parts.normals, entry.parts.albedo
                _set_mesh(self._scene, entry.node, self._vehicle_mesh(entry))

    def _cull_outside_view(self, cam_pose: np.ndarray, camera: CameraModel) -> None:
        """Realistic look: hide the roadside cells, far-set cells, sky-dome sectors and vehicle shadows whose
        bounding boxes lie wholly outside the view of ``camera`` at ``cam_pose`` (they would draw no pixel: the
        same image, less work per frame).

        Only nodes never drawn in a sub-window id pass are culled (those passes see beyond the image)."""
        real = self._real
        fixed = [n for n, _ in real._cells if n.mesh.is_visible] + real.far_nodes     # static: boxes cached
        moving = real.dome_nodes + [e.shadow_node for e in self._vehicles.values() if e.shadow_node is not None]
        corners = [self._static_box(n) for n in fixed]
        if moving:
            model = visibility.box_corners(np.stack([_mesh_bounds(n.mesh) for n in moving]))     # (M, 8, 3)
            mats = np.stack([passes.node_pose(self._scene, n) for n in moving])                  # (M, 4, 4)
            corners.append(np.einsum("sij,skj->ski", mats[:, :3, :3], model) + mats[:, None, :3, 3])
        if not corners:
            return
        world = np.concatenate([np.reshape(c, (-1, 8, 3)) for c in corners])
        to_cam = np.linalg.inv(cam_pose)
        cam = (world @ to_cam[:3, :3].T + to_cam[:3, 3]) * np.array([1.0, -1.0, -1.0])    # OpenGL -> OpenCV axes
        out = visibility.outside_view(cam, camera, ZNEAR_M)
        for node, o in zip(fixed + moving, out.tolist()):
            node.mesh.is_visible = not o       # fixed: visible so far; moving: shown again when back in view

    def _occluders_in_front(self, depth_m: float) -> list[pyrender.Node]:
        """Realistic look: the roadside occluder nodes whose bounding box reaches nearer to the camera than
        ``depth_m`` (the farthest drawn vehicle corner's depth, m). The others lie wholly behind every
        vehicle pixel: in the id pass they could only cover background, which ends as -1 either way."""
        nodes = self._real.occluder_nodes
        if not nodes:
            return []
        corners = np.stack([self._static_box(n) for n in nodes])                   # (O, 8, 3) W, cached per node
        to_cam = np.linalg.inv(passes.node_pose(self._scene, self._cam_node))
        depth = -(corners @ to_cam[2, :3] + to_cam[2, 3])                         # OpenGL looks along -Z
        near = depth.min(axis=1) < depth_m + 1.0
        return [n for n, k in zip(nodes, near.tolist()) if k]

    def _static_box(self, node: pyrender.Node) -> np.ndarray:
        """(8, 3) world corners of a static node's bounding box (cached)."""
        corners = self._static_corners.get(node)
        if corners is None:
            pose = passes.node_pose(self._scene, node)
            corners = visibility.box_corners(_mesh_bounds(node.mesh))[0] @ pose[:3, :3].T + pose[:3, 3]
            self._static_corners[node] = corners
        return corners

    @staticmethod
    def _id_region(boxes: np.ndarray, drawn: np.ndarray, camera: CameraModel) -> tuple[int, int, int, int]:
        """Realistic look: the image rectangle (x0, y0, x1, y1) that holds every drawn vehicle's projected box.

        Outside the drawn vehicles' boxes no pixel can hold a vehicle, so there a roadside occluder's code and
        the background both end as -1 in the id mask, and :func:`visibility.boxes_touching` looks inside the
        boxes only: an id pass drawn in this rectangle alone gives the same truth."""
        b = np.nan_to_num(boxes[drawn], nan=0.0, posinf=1e9, neginf=-1e9)
        x0, y0 = np.floor(b[:, :2].min(axis=0)) - 1
        x1, y1 = np.ceil(b[:, 2:].max(axis=0)) + 2
        w, h = camera.width, camera.height
        return int(np.clip(x0, 0, w)), int(np.clip(y0, 0, h)), int(np.clip(x1, 0, w)), int(np.clip(y1, 0, h))

    def _set_intrinsics(self, fx: float, fy: float, cx: float, cy: float) -> None:
        self._cam.fx, self._cam.fy = fx, fy
        self._cam.cx, self._cam.cy = cx + PIXEL_CENTRE_SHIFT, cy + PIXEL_CENTRE_SHIFT

    @contextlib.contextmanager
    def _gl(self):
        """This renderer's GL context current (other renderers may share the thread)."""
        platform = self._pr._platform
        platform.make_current()
        try:
            yield
        finally:
            platform.make_uncurrent()

    def _move_camera(self, world: WorldState) -> None:
        """Set :attr:`frame_camera` to the true camera of ``world``'s frame (once per frame)."""
        if self._motion is None or self._motion_frame == world.frame:
            return
        self.frame_camera = self._motion.camera(int(world.frame), float(world.ego.speed))
        self._motion_frame = int(world.frame)

    def _prepare(self, world: WorldState):
        """Sync the scene to ``world``; return nodes, projected 3-D boxes, camera-frame corners, drawn flags."""
        if self._pr is None:
            raise RuntimeError("Renderer is closed")
        self._move_camera(world)
        c = self._drawn(self.frame_camera)
        vehicles = tuple(world.vehicles)
        cam_pose = geometry.camera_pose_world(world.ego, c, self._profile, self._plan)
        nodes = self._sync_vehicles(vehicles, cam_pose[:3, 3])
        self._scene.set_pose(self._cam_node, cam_pose)
        if self._real is not None:
            self._real.follow_camera(self._scene, cam_pose)
            self._level_of_detail(vehicles, cam_pose[:3, 3])
            self._cull_outside_view(cam_pose, c)
        heights = np.array([vehicle_height(v.length, v.width, v.body) for v in vehicles])
        corners_cam = c.ego_to_cam(geometry.vehicle_corners_ego(vehicles, world.ego, c, heights, self._profile,
                                                                  self._plan))
        boxes = visibility.projected_boxes(corners_cam, c, ZNEAR_M)
        in_front = (corners_cam[..., 2] > ZNEAR_M).any(axis=1)
        drawn = (in_front & (boxes[:, 2] >= -0.5) & (boxes[:, 0] <= c.width - 0.5)
                 & (boxes[:, 3] >= -0.5) & (boxes[:, 1] <= c.height - 0.5))
        for node, d in zip(nodes, drawn):
            node.mesh.is_visible = bool(d)
        return vehicles, nodes, boxes, corners_cam, drawn

    # ------------------------------------------------------------------ render
    def render(self, world: WorldState) -> RenderedFrame:
        """Colour image, id mask and unoccluded pixel counts of one world state.

        The id pass is issued right after the colour pass, and (without ``conditions``, whose effects need the
        truth) the image is finished while llvmpipe still rasterises the id pass: the same passes and pixels,
        less waiting."""
        vehicles, nodes, boxes, corners_cam, drawn = self._prepare(world)
        c = self._drawn(self.frame_camera)
        self._set_intrinsics(c.fx, c.fy, c.cx, c.cy)
        seg_map = {n: _seg_colour(v.id + 1) for n, v, d in zip(nodes, vehicles, drawn) if d}
        region = image = hidden_by_roadside = None
        if seg_map and self._real is not None:
            region = self._id_region(boxes, drawn, c)
            seg_map.update({n: _seg_colour(OCCLUDER_CODE)
                            for n in self._occluders_in_front(corners_cam[drawn][..., 2].max())})
        with self._gl():
            self._passes.update(self._scene)
            self._passes.draw_colour(self._scene, c.width, c.height)
            ticket = self._passes.draw_ids(self._scene, c.width, c.height, seg_map, region) if seg_map else None
            bgr, depth = self._passes.read_colour(c.width, c.height, want_depth=self._lighting is not None)
            if self._lighting is None:
                image = self._finish_image(self._lens.linear(bgr) if self._lens is not None else bgr, world)
            if ticket is not None:
                codes = self._passes.read_ids(ticket)[::-1]
                if self._real is not None:
                    roadside_px = codes == OCCLUDER_CODE
                    hidden_by_roadside = visibility.boxes_touching(roadside_px, boxes)
                    codes = np.where(roadside_px, 0, codes)
                id_mask = codes.astype(np.int32) - 1
            else:
                id_mask = np.full((c.height, c.width), -1, dtype=np.int32)
            amodal = {} if self.amodal else None
            full = self._full_pixels(id_mask, vehicles, nodes, boxes, corners_cam, drawn, also=hidden_by_roadside,
                                     amodal=amodal)
        if self._lens is not None:   # the pinhole canvas onto the distorted image
            canvas_ids, id_mask = id_mask, self._lens.nearest(id_mask)
            full = self._lens.full_pixels(full, canvas_ids, id_mask)
        if image is None:
            if self._lens is not None:
                bgr, depth = self._lens.linear(bgr), self._lens.nearest(depth)
            z = effects.linear_depth(depth, ZNEAR_M, ZFAR_M)
            image = effects.apply(bgr, z, id_mask, world, self.scenario,
                                  self._lighting, self._ray_factor)
            if self._real is not None:
                image = self._real.sensor(image, world.frame)
        frame = RenderedFrame(world.frame, image, id_mask, full, None if self._motion is None else self.frame_camera)
        if amodal:
            frame.amodal_boxes = self._amodal_in_image(amodal)
        return frame

    def _amodal_in_image(self, amodal: dict) -> dict[int, np.ndarray]:
        """id -> silhouette (canvas px: a box, or with a lens outline points) as a box on the image, clipped."""
        c = self.frame_camera
        out = {}
        for vid, shape in amodal.items():
            box = shape if self._lens is None else amodal_mod.distorted_box(shape, (self._lens.x0, self._lens.y0), c)
            box = amodal_mod.clip_box(box, c.width, c.height)
            if box is not None:
                out[vid] = box
        return out

    def _finish_image(self, bgr: np.ndarray, world: WorldState) -> np.ndarray:
        """The frame's image from its (lens-warped) colour pass without ``conditions``: the simple sensor, then
        the realistic look's camera."""
        image = apply_sensor(bgr, self._noise_std, self._blur_px, self._seed, world.frame)
        if self._real is not None:
            image = self._real.sensor(image, world.frame)
        return image

    def _full_pixels(self, id_mask, vehicles, nodes, boxes, corners_cam, drawn, force=False,
                     also: np.ndarray | None = None, amodal: dict | None = None) -> dict[int, float]:
        """Unoccluded, unbounded pixel count of every vehicle visible in ``id_mask``; ``also``: (N,) bool,
        vehicles to render unoccluded besides those the shortcut picks (e.g. hidden by the roadside).
        ``amodal``: filled with id -> the silhouette of each vehicle drawn alone, in canvas px (its box; with
        a lens, its outline points)."""
        c = self._drawn(self.frame_camera)
        ids, counts = np.unique(id_mask, return_counts=True)      # ascending ids (np.bincount: 3x slower)
        visible = ids[ids >= 0].tolist()
        index = {v.id: i for i, v in enumerate(vehicles)}
        need = visibility.needs_full_render(boxes, corners_cam, drawn, c.width, c.height)
        if also is not None:
            need = need | also
        full = {int(vid): float(n) for vid, n in zip(ids, counts) if vid >= 0}
        todo = [index[vid] for vid in visible if force or need[index[vid]]]
        try:
            for win, members in visibility.plan_full_renders(boxes, todo, c.width, c.height, c.width * c.height):
                self._set_intrinsics(*win.intrinsics(c))
                codes = self._passes.ids(self._scene, win.width, win.height,
                                         {nodes[i]: _seg_colour(1 << k) for k, i in enumerate(members)},
                                         role="window", overlay=True)
                n_px = visibility.bit_counts(codes, len(members))
                for k, i in enumerate(members):
                    vid = vehicles[i].id
                    full[vid] = max(float(n_px[k]) * win.scale ** 2, full[vid])
                if amodal is not None:
                    self._silhouettes(codes[::-1], win, members, vehicles, amodal)
        finally:
            self._set_intrinsics(c.fx, c.fy, c.cx, c.cy)
        return full

    def _silhouettes(self, codes: np.ndarray, win, members: list[int], vehicles, amodal: dict) -> None:
        """Fill ``amodal`` from one sub-window's id pass (``codes`` top row first)."""
        if self._lens is None:
            for k, box in amodal_mod.window_silhouette_boxes(codes, win.x0, win.y0, win.scale, len(members)).items():
                amodal[vehicles[members[k]].id] = box
            return
        for k, i in enumerate(members):
            pts = amodal_mod.window_silhouette_outline(codes, k, win.x0, win.y0, win.scale)
            if len(pts):
                amodal[vehicles[i].id] = pts

    def full_pixels_rendered(self, world: WorldState, id_mask: np.ndarray) -> dict[int, float]:
        """Like ``RenderedFrame.full_pixels`` but every vehicle through a sub-window render
        (no shortcut for unhidden vehicles); for tests and checks (a pinhole camera's: with a lens,
        ``id_mask`` and the counts are the canvas's)."""
        vehicles, nodes, boxes, corners_cam, drawn = self._prepare(world)
        with self._gl():
            self._passes.update(self._scene)
            return self._full_pixels(id_mask, vehicles, nodes, boxes, corners_cam, drawn, force=True)
