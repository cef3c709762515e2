"""The colour and id passes, drawn with OpenGL directly over a pyrender scene.

pyrender keeps the scene, the GL context, the uploaded meshes and the shader programs;
this module replaces its per-pass work (``Renderer._forward_pass`` and the framebuffer
read), issuing the same draws with the same GL state and uniforms, so the pixels are
pyrender's (``tests/test_render_passes.py``): per pass the camera uniforms, blend/cull/fill
state and material uniforms are set once instead of per mesh, uniform locations are looked
up once per program, node poses and the draw order once per frame, and each framebuffer
(colour, resolved, ids) is kept and only grown, where pyrender reallocated its own whenever
the size changed (every sub-window id pass).

Per frame (:meth:`Passes.update`) only the nodes visible then are posed and ordered (poses read
straight from a root child's matrix, the product pyrender's ``get_pose`` forms without its networkx
path search); a pass may be split into its draws (``draw_colour``, ``draw_ids``) and its read
(``read_colour``, ``read_ids``) so the caller can work while llvmpipe rasterises; an id pass may be
limited to a region of the frame (scissor: the same codes there, 0 elsewhere).

Draw order (:func:`sorted_mesh_nodes`): far to near as pyrender does, ties in insertion
order (``node._draw_order``; pyrender iterates a ``set``, so nodes at the same distance,
like the road meshes all at the origin, were drawn in an order that changed from one
renderer to the next, and where their depths tie a pixel took either colour).

Colour pass: pyrender's FLAT shader into a 4x multisampled framebuffer, resolved by a
blit, read as RGBA (Mesa's read without conversion) and returned as BGR; with ``want_depth``
also the resolved window depth 0..1. Id pass: pyrender's SEG shader into a single-sample
framebuffer (each pixel holds the primitive covering its centre, as pyrender's
multisampling-off rasterisation into its 4x buffer did), read as one uint32 per pixel.

Textured materials (a ``baseColorTexture`` and the other glTF textures of a
MetallicRoughnessMaterial): uploaded in :meth:`Passes.update` as pyrender's ``_update_context``
does (``scene``'s mesh textures into the renderer's ``_mesh_textures``, so pyrender frees them
and its own render finds them uploaded), bound in the colour pass as ``_bind_and_draw_primitive``
does (texture units from 0 in pyrender's order, the sampler uniform set to the unit). With
``max_anisotropy`` > 1 each texture uploaded here also gets ``GL_TEXTURE_MAX_ANISOTROPY``
(clamped to what the GL offers); it is a state of the texture object, so pyrender's own render of
the same, already uploaded texture samples it the same way. Off by default: llvmpipe (Mesa 22.3)
samples anisotropically in software, 8-16 s per 640x360 frame of textured road at 2x..16x
against ~13 ms trilinear; on a GPU it is free.
"""

from __future__ import annotations

import ctypes

import cv2
import numpy as np
import pyrender
from OpenGL import GL
from OpenGL.raw.GL.VERSION.GL_2_0 import glUniform3fv as _raw_uniform3fv
from OpenGL.raw.GL.VERSION.GL_2_0 import glUniformMatrix4fv as _raw_uniform_matrix4fv
from pyrender.constants import ProgramFlags, RenderFlags, TexFlags

SAMPLES = 4
_FLOATS = ctypes.POINTER(ctypes.c_float)
GL_TEXTURE_MAX_ANISOTROPY = 0x84FE        # GL 4.6 / ARB_texture_filter_anisotropic
GL_MAX_TEXTURE_MAX_ANISOTROPY = 0x84FF
_TEXTURES = ((TexFlags.NORMAL, "normalTexture", "material.normal_texture"),     # pyrender's binding order
             (TexFlags.OCCLUSION, "occlusionTexture", "material.occlusion_texture"),
             (TexFlags.EMISSIVE, "emissiveTexture", "material.emissive_texture"),
             (TexFlags.BASE_COLOR, "baseColorTexture", "material.base_color_texture"),
             (TexFlags.METALLIC_ROUGHNESS, "metallicRoughnessTexture", "material.metallic_roughness_texture"))


class _Framebuffer:
    """A colour (RGBA8) + depth (24 bit) framebuffer of one size, multisampled or not."""

    def __init__(self, width: int, height: int, samples: int) -> None:
        self.width, self.height = width, height
        self.colour, self.depth = GL.glGenRenderbuffers(2)
        for rb, fmt in ((self.colour, GL.GL_RGBA), (self.depth, GL.GL_DEPTH_COMPONENT24)):
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, rb)
            if samples:
                GL.glRenderbufferStorageMultisample(GL.GL_RENDERBUFFER, samples, fmt, width, height)
            else:
                GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, fmt, width, height)
        self.fb = GL.glGenFramebuffers(1)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self.fb)
        GL.glFramebufferRenderbuffer(GL.GL_DRAW_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_RENDERBUFFER, self.colour)
        GL.glFramebufferRenderbuffer(GL.GL_DRAW_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_RENDERBUFFER, self.depth)

    def delete(self) -> None:
        GL.glDeleteFramebuffers(1, [self.fb])
        GL.glDeleteRenderbuffers(2, [self.colour, self.depth])


def sorted_mesh_nodes(scene: pyrender.Scene, poses: dict, nodes=None) -> list:
    """Mesh nodes (``nodes``, default all of ``scene``'s) in draw order: solid then transparent, each far to
    near from the camera, ties in insertion order."""
    cam = poses[scene.main_camera_node][:3, 3]
    nodes = sorted(scene.mesh_nodes if nodes is None else nodes, key=lambda n: getattr(n, "_draw_order", -1))
    solid = [n for n in nodes if not n.mesh.is_transparent]
    trans = [n for n in nodes if n.mesh.is_transparent]
    far_first = lambda n: -np.linalg.norm(poses[n][:3, 3] - cam)  # noqa: E731
    return sorted(solid, key=far_first) + sorted(trans, key=far_first)


_EYE = np.eye(4)


def node_pose(scene: pyrender.Scene, node) -> np.ndarray:
    """``scene.get_pose(node)`` without its networkx path search for a child of the scene's root (every node
    the renderer adds): the same product ``node.matrix @ eye(4)``, so the same bits."""
    parents = scene._digraph._succ.get(node)
    if node._matrix is not None and parents is not None and len(parents) == 1 and "world" in parents:
        return np.dot(node._matrix, _EYE)
    return scene.get_pose(node)


class Passes:
    """The passes of one :class:`pyrender.OffscreenRenderer` (call with its context current)."""

    def __init__(self, pr: pyrender.OffscreenRenderer, max_anisotropy: float = 1.0) -> None:
        self._inner = pr._renderer
        self._anisotropy = float(max_anisotropy)
        self._fbs: dict[str, _Framebuffer] = {}
        self._locations: dict[tuple[int, str], int] = {}
        self._programs: dict[tuple, object] = {}
        self._frame: tuple | None = None     # (draw order, pose pointers, V, cam_pos) of the current frame
        self._textures_known = False

    def delete(self) -> None:
        """Free the framebuffers (context current)."""
        for fb in self._fbs.values():
            fb.delete()
        self._fbs.clear()

    def update(self, scene: pyrender.Scene) -> None:
        """Upload meshes new to the scene, free removed ones, and take the node poses and draw order
        for the passes that follow (once per frame, after the poses and ``mesh.is_visible`` flags are set:
        only the nodes visible now are ordered and drawn).

        pyrender's ``_update_context`` without its shadow-map bookkeeping (no shadows); the textures are
        gathered again only when the set of meshes changed."""
        inner, nodes = self._inner, scene.mesh_nodes
        meshes = {n.mesh for n in nodes}
        if meshes != inner._meshes or not self._textures_known:
            for mesh in meshes - inner._meshes:
                for p in mesh.primitives:
                    p._add_to_context()
            for mesh in inner._meshes - meshes:
                for p in mesh.primitives:
                    p.delete()
            inner._meshes = meshes
            textures = set()
            for mesh in meshes:
                for p in mesh.primitives:
                    textures |= p.material.textures
            for texture in textures - inner._mesh_textures:
                texture._add_to_context()
                self._set_anisotropy(texture)
            for texture in inner._mesh_textures - textures:
                texture.delete()
            inner._mesh_textures = textures
            self._textures_known = True
        cam_node = scene.main_camera_node
        visible = [n for n in nodes if n.mesh.is_visible]
        poses = {n: node_pose(scene, n) for n in visible}
        poses[cam_node] = node_pose(scene, cam_node)
        order = sorted_mesh_nodes(scene, poses, visible)
        # the float32 model matrices as ctypes pointers (each keeps its array alive): the raw
        # glUniformMatrix4fv takes them without PyOpenGL's array conversion (2 us a call instead of 9)
        model = {n: np.ascontiguousarray(poses[n], dtype=np.float32).ctypes.data_as(_FLOATS) for n in order}
        self._frame = (order, model, np.linalg.inv(poses[cam_node]).astype(np.float32),
                       poses[cam_node][:3, 3].astype(np.float32))

    def _set_anisotropy(self, texture) -> None:
        if self._anisotropy <= 1.0:
            return
        most = float(GL.glGetFloatv(GL_MAX_TEXTURE_MAX_ANISOTROPY))
        GL.glBindTexture(texture.tex_type, texture._texid)
        GL.glTexParameterf(texture.tex_type, GL_TEXTURE_MAX_ANISOTROPY, min(self._anisotropy, most))
        GL.glBindTexture(texture.tex_type, 0)

    def _program(self, primitive, flags: int):
        cached = primitive.__dict__.setdefault("_passes_programs", {}).get(flags)
        if cached is not None and cached[0] is primitive.material and cached[1] is self._programs:
            return cached[2]
        key = (flags, primitive.buf_flags, type(primitive.material), primitive.material.tex_flags, primitive.mode)
        program = self._programs.get(key)
        if program is None:
            program = self._programs[key] = self._inner._get_primitive_program(primitive, flags,
                                                                               ProgramFlags.USE_MATERIAL)
        primitive._passes_programs[flags] = (primitive.material, self._programs, program)
        return program

    def _fb(self, role: str, width: int, height: int, samples: int = 0) -> _Framebuffer:
        """The framebuffer of ``role``, grown to hold ``width`` x ``height``: a pass draws into its lower-left
        corner and reads that back (the pixels are the same as in a framebuffer of the pass's size), so
        sub-window id passes of changing sizes share one framebuffer instead of reallocating."""
        fb = self._fbs.get(role)
        if fb is None or fb.width < width or fb.height < height:
            if fb is not None:
                fb.delete()
                width, height = max(width, fb.width), max(height, fb.height)
            fb = self._fbs[role] = _Framebuffer(width, height, samples)
        return fb

    def _set(self, program, name: str, setter, *args) -> None:
        key = (program._program_id, name)
        loc = self._locations.get(key)
        if loc is None:
            loc = self._locations[key] = GL.glGetUniformLocation(program._program_id, name)
        if loc != -1:
            setter(loc, *args)

    def _draw(self, scene: pyrender.Scene, width: int, height: int, flags: int, seg_node_map: dict | None,
              scissor: tuple[int, int, int, int] | None = None, small_in_large: bool = False,
              overlay: bool = False) -> None:
        """pyrender's forward pass into the bound framebuffer: same clear, state, uniforms and draw order;
        with ``scissor`` (x, y, w, h, GL window pixels) the draws touch only that rectangle (the clear all of
        ``width`` x ``height``); ``small_in_large``: the pass covers a small corner of a grown framebuffer, clear
        only that corner (the pixels read back are the same either way). ``overlay`` (id pass): no depth
        test, each fragment's colour OR-ed into the pixel (``GL_COLOR_LOGIC_OP``), so a pixel holds the OR
        of the codes of every node covering its centre."""
        seg = bool(flags & RenderFlags.SEG)
        GL.glViewport(0, 0, width, height)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthMask(GL.GL_FALSE if overlay else GL.GL_TRUE)
        GL.glDepthFunc(GL.GL_ALWAYS if overlay else GL.GL_LESS)
        GL.glDepthRange(0.0, 1.0)
        GL.glClearColor(*((0.0, 0.0, 0.0, 1.0) if seg else scene.bg_color))
        if small_in_large:      # llvmpipe: a scissored clear is a drawn quad, cheaper only on a small part
            GL.glEnable(GL.GL_SCISSOR_TEST)
            GL.glScissor(0, 0, width, height)
        GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
        if scissor is not None:
            GL.glEnable(GL.GL_SCISSOR_TEST)
            GL.glScissor(*scissor)
        (GL.glDisable if seg else GL.glEnable)(GL.GL_MULTISAMPLE)
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_BACK)
        GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
        GL.glDisable(GL.GL_PROGRAM_POINT_SIZE)
        GL.glEnable(GL.GL_BLEND)
        GL.glBlendFunc(GL.GL_ONE, GL.GL_ZERO)
        if overlay:
            GL.glEnable(GL.GL_COLOR_LOGIC_OP)
            GL.glLogicOp(GL.GL_OR)

        order, pointers, V, cam_pos = self._frame
        P = scene.main_camera_node.camera.get_projection_matrix(width=width, height=height)
        program, material = None, None
        for node in order:
            mesh = node.mesh
            if not mesh.is_visible or (seg and node not in seg_node_map):
                continue
            for primitive in mesh.primitives:
                p = self._program(primitive, flags)
                if p is not program:
                    program, material = p, None
                    program._bind()
                    self._set(program, "V", GL.glUniformMatrix4fv, 1, GL.GL_TRUE, V)
                    self._set(program, "P", GL.glUniformMatrix4fv, 1, GL.GL_TRUE, P)
                    self._set(program, "cam_pos", GL.glUniform3fv, 1, cam_pos)
                if seg:
                    colour = (np.asanyarray(seg_node_map[node]) / 255.0).astype(np.float32)
                    self._set(program, "color", _raw_uniform3fv, 1, colour.ctypes.data_as(_FLOATS))
                elif primitive.material is not material:
                    material = primitive.material
                    self._material(program, material)
                self._set(program, "M", _raw_uniform_matrix4fv, 1, GL.GL_TRUE, pointers[node])
                GL.glBindVertexArray(primitive._vaid)
                n_instances = 1 if primitive.poses is None else len(primitive.poses)
                if primitive.indices is not None:
                    GL.glDrawElementsInstanced(primitive.mode, primitive.indices.size, GL.GL_UNSIGNED_INT,
                                               None, n_instances)
                else:
                    GL.glDrawArraysInstanced(primitive.mode, 0, len(primitive.positions), n_instances)
                GL.glBindVertexArray(0)
        if program is not None:
            GL.glUseProgram(0)
        GL.glDisable(GL.GL_SCISSOR_TEST)
        if overlay:
            GL.glDisable(GL.GL_COLOR_LOGIC_OP)
            GL.glDepthMask(GL.GL_TRUE)

    def _material(self, program, material) -> None:
        """The textures, material uniforms and blend/cull state pyrender sets for a metallic-roughness material."""
        if not isinstance(material, pyrender.MetallicRoughnessMaterial) or material.wireframe:
            raise NotImplementedError("passes draw filled MetallicRoughnessMaterial meshes only")
        unit = 0
        for flag, attr, uniform in _TEXTURES:
            if material.tex_flags & flag:
                GL.glActiveTexture(GL.GL_TEXTURE0 + unit)
                getattr(material, attr)._bind()
                self._set(program, uniform, GL.glUniform1i, unit)
                unit += 1
        f32 = lambda v: np.asarray(v, dtype=np.float32)  # noqa: E731
        self._set(program, "material.emissive_factor", GL.glUniform3fv, 1, f32(material.emissiveFactor))
        self._set(program, "material.base_color_factor", GL.glUniform4fv, 1, f32(material.baseColorFactor))
        self._set(program, "material.metallic_factor", GL.glUniform1f, float(material.metallicFactor))
        self._set(program, "material.roughness_factor", GL.glUniform1f, float(material.roughnessFactor))
        if material.alphaMode == "BLEND":
            GL.glBlendFunc(GL.GL_SRC_ALPHA, GL.GL_ONE_MINUS_SRC_ALPHA)
        else:
            GL.glBlendFunc(GL.GL_ONE, GL.GL_ZERO)
        if material.doubleSided:
            GL.glDisable(GL.GL_CULL_FACE)
        else:
            GL.glEnable(GL.GL_CULL_FACE)
            GL.glCullFace(GL.GL_BACK)

    def colour(self, scene: pyrender.Scene, width: int, height: int,
               want_depth: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """(H, W, 3) uint8 BGR image, top row first; with ``want_depth`` also (H, W) float32 window depth 0..1."""
        self.draw_colour(scene, width, height)
        return self.read_colour(width, height, want_depth)

    def draw_colour(self, scene: pyrender.Scene, width: int, height: int) -> None:
        """The first half of :meth:`colour`: issue the draws (llvmpipe rasterises them on its threads while this
        thread issues the next pass, e.g. :meth:`draw_ids`); :meth:`read_colour` waits for and reads them."""
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._fb("colour", width, height, SAMPLES).fb)
        self._draw(scene, width, height, RenderFlags.FLAT, None)

    def read_colour(self, width: int, height: int, want_depth: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """The second half of :meth:`colour`: resolve and read the last :meth:`draw_colour` of this size."""
        ms, out = self._fb("colour", width, height, SAMPLES), self._fb("resolved", width, height)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, ms.fb)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, out.fb)
        GL.glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL.GL_COLOR_BUFFER_BIT, GL.GL_NEAREST)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, out.fb)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        rgba = np.empty((height, width, 4), dtype=np.uint8)
        GL.glReadPixels(0, 0, width, height, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE, rgba)
        bgr = cv2.flip(cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGR), 0)
        if not want_depth:
            return bgr, None
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, ms.fb)
        GL.glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL.GL_DEPTH_BUFFER_BIT, GL.GL_NEAREST)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, out.fb)
        dbuf = GL.glReadPixels(0, 0, width, height, GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT)
        return bgr, np.frombuffer(dbuf, dtype=np.float32).reshape(height, width)[::-1]

    def ids(self, scene: pyrender.Scene, width: int, height: int, seg_node_map: dict,
            region: tuple[int, int, int, int] | None = None, role: str = "ids", overlay: bool = False) -> np.ndarray:
        """(H, W) uint32 codes R | G << 8 | B << 16 of ``seg_node_map``'s colours (0: nothing), bottom row first.

        ``region``: (x0, y0, x1, y1), image pixels (columns x0..x1 - 1 and rows y0..y1 - 1 counted from the top,
        clipped to the frame): only there are the nodes drawn and read back; everywhere else the codes are 0.
        Inside it the codes are those of the whole pass (the same rasteriser, pixel grid and depth test).
        ``role``: the framebuffer drawn into (passes of very different sizes, such as the frame's and the
        sub-windows', keep theirs apart so that neither clears and stores more pixels than it needs).
        ``overlay``: no depth test, the codes OR-ed (:meth:`_draw`): give the nodes disjoint bits and each
        pixel says which of them cover it, hidden or not."""
        return self.read_ids(self.draw_ids(scene, width, height, seg_node_map, region, role, overlay))

    def draw_ids(self, scene: pyrender.Scene, width: int, height: int, seg_node_map: dict,
                 region: tuple[int, int, int, int] | None = None, role: str = "ids", overlay: bool = False) -> tuple:
        """The first half of :meth:`ids` (see :meth:`draw_colour`); returns the ticket :meth:`read_ids` takes."""
        fb = self._fb(role, width, height)
        x0, y0, x1, y1 = (0, 0, width, height) if region is None else (
            max(0, int(region[0])), max(0, int(region[1])), min(width, int(region[2])), min(height, int(region[3])))
        if x1 <= x0 or y1 <= y0:
            return width, height, None, role
        whole = (x0, y0, x1, y1) == (0, 0, width, height)
        rect = (x0, height - y1, x1 - x0, y1 - y0)         # GL window rectangle: rows count from the bottom
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, fb.fb)
        self._draw(scene, width, height, RenderFlags.SEG, seg_node_map, None if whole else rect,
                   small_in_large=4 * width * height <= fb.width * fb.height, overlay=overlay)
        return width, height, rect, role

    def read_ids(self, ticket: tuple) -> np.ndarray:
        """The second half of :meth:`ids`: read the pass :meth:`draw_ids` issued (no other id pass in between)."""
        width, height, rect, role = ticket
        if rect is None:
            return np.zeros((height, width), dtype=np.uint32)
        x, y, w, h = rect
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._fb(role, width, height).fb)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        buf = GL.glReadPixels(x, y, w, h, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE)
        codes = np.frombuffer(buf, dtype="<u4").reshape(h, w) & 0xFFFFFF
        if (w, h) == (width, height):
            return codes
        out = np.zeros((height, width), dtype=np.uint32)
        out[y:y + h, x:x + w] = codes
        return out
