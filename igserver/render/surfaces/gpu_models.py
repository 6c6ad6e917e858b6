"""Models resident on the GPU: vertex/index buffers, material textures, instance buffers.

One draw call per primitive and pass draws every instance of it (instancing): the per-instance
data is the camera-relative model matrix (4 vec4) plus material factors (tint rgb, metallic,
roughness), 96 bytes, written once per frame.
"""

from __future__ import annotations

import hashlib
import logging
import os
import time

import moderngl
import numpy as np

from ...assets.gltf import model_path
from ...scene.model import MAX_ENTITIES
from ..bindings import PASS_UNITS, use_textures, write_buffer
from .loader import MaterialData, ModelData, load_model
from .models import BUILTIN, box_model

log = logging.getLogger(__name__)

INSTANCE_FLOATS = 24  # 16 matrix + 4 tint/metallic + 4 (roughness, unused x3)
INSTANCE_FORMAT = "4f 4f 4f 4f 4f 4f/i"
INSTANCE_ATTRIBUTES = ("in_model0", "in_model1", "in_model2", "in_model3", "in_tint", "in_extra")
GL_SRGB8_ALPHA8 = 0x8C43
# Anisotropic filtering keeps grazing surfaces (a pier deck, a ship's side) sharp; on llvmpipe it
# cost ~30 % of the surfaces pass at 640x360 (measured on the demo), so the CPU path uses trilinear.
GPU_ANISOTROPY = 8.0


class Textures:
    """Material textures with shared 1x1 defaults for the slots a material leaves empty."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        software = "llvmpipe" in str(ctx.info.get("GL_RENDERER", "")).lower()
        self.anisotropy = 1.0 if software else GPU_ANISOTROPY
        self.white = self._make(np.full((1, 1, 4), 255, np.uint8), srgb=False)
        self.white_srgb = self._make(np.full((1, 1, 4), 255, np.uint8), srgb=True)
        self.flat_normal = self._make(np.array([[[128, 128, 255, 255]]], np.uint8), srgb=False)
        # One texture per distinct image: materials that share an image (the generated models'
        # paints and woods) share its texture, so drawing them one after another binds nothing.
        self._by_content: dict[tuple, moderngl.Texture] = {}

    def _make(self, rgba: np.ndarray, srgb: bool) -> moderngl.Texture:
        h, w = rgba.shape[:2]
        tex = self.ctx.texture((w, h), 4, np.ascontiguousarray(rgba).tobytes(),
                               internal_format=GL_SRGB8_ALPHA8 if srgb else None)
        if w > 1 or h > 1:
            tex.build_mipmaps()
            tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            tex.anisotropy = self.anisotropy
        return tex

    def from_image(self, image, srgb: bool, default: moderngl.Texture) -> moderngl.Texture:
        if image is None:
            return default
        rgba = np.ascontiguousarray(image, dtype=np.uint8)
        key = (srgb, rgba.shape, hashlib.sha1(rgba.tobytes()).digest())
        if key not in self._by_content:
            self._by_content[key] = self._make(rgba, srgb)
        return self._by_content[key]


class GpuMaterial:
    def __init__(self, textures: Textures, mat: MaterialData):
        self.data = mat
        self.base = textures.from_image(mat.base_image, True, textures.white_srgb)
        self.mr = textures.from_image(mat.mr_image, False, textures.white)
        self.normal = textures.from_image(mat.normal_image, False, textures.flat_normal)
        self.occlusion = textures.from_image(mat.occlusion_image, False, textures.white)
        self.emissive = textures.from_image(mat.emissive_image, True, textures.white_srgb)
        self.has_normal = mat.normal_image is not None
        # the textures bound for this material on units BASE_TEX.. (draws that share them are drawn
        # one after another)
        self.textures = (self.base, self.mr, self.normal, self.occlusion, self.emissive)
        self.texture_set = tuple(id(t) for t in self.textures)
        self.uniforms = {
            "u_base_factor": tuple(mat.base_factor),
            "u_metallic_factor": mat.metallic,
            "u_roughness_factor": mat.roughness,
            "u_normal_scale": 1.0,
            "u_occlusion_strength": 1.0 if mat.occlusion_image is not None else 0.0,
            "u_emissive_factor": tuple(mat.emissive),
            "u_alpha_mode": mat.alpha_mode,
            "u_alpha_cutoff": mat.alpha_cutoff,
            "u_has_normal_tex": int(self.has_normal),
        }
        # What a draw of this material sets, its uniforms' values and its textures: a run of draws
        # whose materials have equal values sets them once (most materials differ only in textures).
        self.uniform_state = tuple(sorted(self.uniforms.items()))

    def bind(self) -> None:
        use_textures(self.textures, PASS_UNITS["BASE_TEX"])


# GpuMaterial.bind binds its five textures on consecutive units from BASE_TEX, in this order.
_MATERIAL_UNITS = ("BASE_TEX", "MR_TEX", "NORMAL_TEX", "OCCLUSION_TEX", "EMISSIVE_TEX")
assert [PASS_UNITS[k] - PASS_UNITS["BASE_TEX"] for k in _MATERIAL_UNITS] == list(range(5))

SAMPLER_UNITS = {"u_base_tex": PASS_UNITS["BASE_TEX"], "u_mr_tex": PASS_UNITS["MR_TEX"], "u_normal_tex": PASS_UNITS["NORMAL_TEX"],
                 "u_occlusion_tex": PASS_UNITS["OCCLUSION_TEX"], "u_emissive_tex": PASS_UNITS["EMISSIVE_TEX"]}


class GpuPrimitive:
    def __init__(self, ctx: moderngl.Context, vertices: np.ndarray, indices: np.ndarray, node: int,
                 material: GpuMaterial):
        self.ctx = ctx
        self.node = node
        self.material = material
        self.vbo = ctx.buffer(vertices.tobytes())
        self.ibo = ctx.buffer(indices.astype(np.uint32).tobytes())
        self.vertex_count = len(indices)
        # one instance buffer per use (camera view, shadow maps): they are filled in turn each frame
        self._instances: dict[str, moderngl.Buffer] = {}
        self._vaos: dict[tuple, moderngl.VertexArray] = {}

    def instance_buffer(self, use: str) -> moderngl.Buffer:
        if use not in self._instances:
            self._instances[use] = self.ctx.buffer(reserve=MAX_ENTITIES * INSTANCE_FLOATS * 4, dynamic=True)
        return self._instances[use]

    def draw(self, program: moderngl.Program, use: str, instances: np.ndarray) -> None:
        """Draw ``instances`` ((n, 24) float32, n <= MAX_ENTITIES) with ``program``."""
        self.draw_rows(program, use, np.ascontiguousarray(instances, dtype=np.float32).tobytes(), len(instances))

    def draw_rows(self, program: moderngl.Program, use: str, data: bytes, count: int) -> None:
        """Draw ``count`` instances whose rows are ``data`` (float32 bytes, 24 a row) with ``program``."""
        buf = self.instance_buffer(use)
        write_buffer(buf, data)
        key = (id(program), use)
        vao = self._vaos.get(key)
        if vao is None:
            vao = self.ctx.vertex_array(program, [
                (self.vbo, "3f 3f 2f", "in_position", "in_normal", "in_uv"),
                (buf, INSTANCE_FORMAT, *INSTANCE_ATTRIBUTES),
            ], index_buffer=self.ibo, index_element_size=4, skip_errors=True)
            self._vaos[key] = vao
        vao.render(moderngl.TRIANGLES, vertices=self.vertex_count, instances=count)


class GpuModel:
    def __init__(self, ctx: moderngl.Context, textures: Textures, model: ModelData):
        self.model = model
        materials: dict[int, GpuMaterial] = {}
        self.primitives = []
        for prim in model.primitives:
            mat = materials.setdefault(id(prim.material), GpuMaterial(textures, prim.material))
            self.primitives.append(GpuPrimitive(ctx, prim.vertices, prim.indices, prim.node, mat))
        self.primitive_nodes = np.array([p.node for p in self.primitives], dtype=np.intp)


MODEL_RECHECK_S = 1.0  # a model file replaced while the IG runs is noticed within this


class ModelCache:
    """Models by asset name, loaded on first use and reloaded when the file changes. A model that
    fails to load is remembered (with the file's identity) and drawn as nothing; ``problems``
    says why, without server paths."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.textures = Textures(ctx)
        self._models: dict[str, tuple[tuple, GpuModel | None]] = {}
        self.problems: dict[str, str] = {}

    def get(self, name: str) -> GpuModel | None:
        try:
            identity = model_identity(name)
        except Exception as exc:  # noqa: BLE001 - a vanished or refused file: draw nothing
            return self._fail(name, None, exc)
        cached = self._models.get(name)
        if cached is not None and cached[0] == identity:
            return cached[1]
        try:
            data = box_model() if name in BUILTIN else load_model(name)
            model = GpuModel(self.ctx, self.textures, data)
        except Exception as exc:  # noqa: BLE001 - any loader failure costs this model only
            return self._fail(name, identity, exc)
        self._models[name] = (identity, model)
        self.problems.pop(name, None)
        return model

    def _fail(self, name: str, identity, exc: Exception) -> None:
        message = str(exc) if isinstance(exc, ValueError) else f"model {name!r} could not be loaded ({type(exc).__name__})"
        if self.problems.get(name) != message:
            log.warning("entity model %r not drawn: %s", name, message)
        self.problems[name] = message
        if identity is not None:
            self._models[name] = (identity, None)
        return None


_identities: dict[tuple, tuple[float, tuple]] = {}


def model_identity(name: str) -> tuple:
    """A model asset's file identity (size, mtime, inode; ("builtin",) for the built-in ones), read
    at most once per MODEL_RECHECK_S: a stat costs ~0.2 ms and the render process asks for every
    entity's model every frame (the model cache, the blended-surfaces check). A vanished or refused
    file raises, and is not remembered."""
    if name in BUILTIN:
        return ("builtin",)
    key = (name, os.environ.get("IGSERVER_ASSETS"))  # the same name may resolve elsewhere
    now = time.monotonic()
    held = _identities.get(key)
    if held is not None and 0.0 <= now - held[0] < MODEL_RECHECK_S:
        return held[1]
    st = os.stat(model_path(name))
    identity = (st.st_size, st.st_mtime_ns, st.st_ino)
    if len(_identities) > 256:
        _identities.clear()
    _identities[key] = (now, identity)
    return identity
