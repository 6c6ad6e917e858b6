"""The atmosphere tables: GPU precompute (compute shaders, float32), disk cache, residency.

``AtmosphereTables.get(ctx, params)`` returns the tables for ``params``, resident per GL context:
the same parameters on the next frame cost a dictionary lookup; new parameters load the tables
from the disk cache (``$IGSERVER_CACHE`` or ``~/.cache/igserver``/atmosphere/<key>.npz, the key a
hash of the parameters, table sizes, orders, TABLE_FORMAT_VERSION and the precompute shader source)
or compute them. The tables depend only on the turbidity class, ozone, quality and orders (never on
the visibility), so a host can make only a few dozen distinct keys; the cache is still bounded:
``$IGSERVER_CACHE_MAX_MB`` (default 300) with least-recently-used eviction (a load touches the file).

At render time the tables sit on fixed texture units (``TABLE_UNITS``) that every pass's
``apply_aerial_perspective`` samples; passes must not use those units for anything else.
"""

from __future__ import annotations

import os
import time
import weakref
from pathlib import Path

import moderngl
import numpy as np

from ..bindings import FRAME_UNITS, use_texture
from ..shaders import ProgramCache, expand, set_uniforms
from .atmosphere_model import AtmosphereParameters

# Texture units reserved for the atmosphere tables in every pass.
TABLE_UNITS = {"u_transmittance_lut": FRAME_UNITS["TRANSMITTANCE"], "u_irradiance_lut": FRAME_UNITS["IRRADIANCE"],
               "u_scattering_lut": FRAME_UNITS["SCATTERING"], "u_single_mie_lut": FRAME_UNITS["SINGLE_MIE"]}
PRECOMPUTE_SHADER = "sky/precompute.glsl"


def cache_dir() -> Path:
    root = os.environ.get("IGSERVER_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "igserver")
    return Path(root) / "atmosphere"


DEFAULT_CACHE_MAX_MB = 300.0


def cache_max_bytes() -> int:
    try:
        mb = float(os.environ.get("IGSERVER_CACHE_MAX_MB", DEFAULT_CACHE_MAX_MB))
    except ValueError:
        mb = DEFAULT_CACHE_MAX_MB
    return int(max(mb, 0.0) * 1024 * 1024)


def evict_least_recently_used(directory: Path, max_bytes: int, keep: Path | None = None) -> list[Path]:
    """Delete the least recently used table files until the directory holds at most max_bytes
    (the file just written, ``keep``, always stays). Returns the deleted paths."""
    try:
        files = [(p.stat().st_mtime, p.stat().st_size, p) for p in directory.glob("*.npz")]
    except OSError:
        return []
    total = sum(size for _, size, _ in files)
    removed = []
    for _, size, path in sorted(files):
        if total <= max_bytes:
            break
        if keep is not None and path == keep:
            continue
        try:
            path.unlink()
            total -= size
            removed.append(path)
        except OSError:
            pass
    return removed


def _groups(size, local) -> tuple[int, int, int]:
    size = tuple(size) + (1,) * (3 - len(size))
    return tuple((s + l - 1) // l for s, l in zip(size, local))


class AtmosphereTables:
    """Resident float32 tables for one set of atmosphere parameters."""

    _resident: "weakref.WeakKeyDictionary[moderngl.Context, AtmosphereTables]" = weakref.WeakKeyDictionary()

    def __init__(self, ctx: moderngl.Context, params: AtmosphereParameters):
        self.ctx = ctx
        self.params = params
        self.key = params.key(expand(PRECOMPUTE_SHADER))
        self.precompute_s = 0.0  # wall time of the GPU precompute (0 when loaded)
        self.load_s = 0.0
        self.from_cache = False
        s = params.sizes
        self.transmittance = self._tex2d(s.transmittance)
        self.irradiance = self._tex2d(s.irradiance)
        self.scattering = self._tex3d(s.scattering)
        self.single_mie = self._tex3d(s.scattering)
        path = cache_dir() / f"{self.key}.npz"
        t0 = time.perf_counter()
        if not self._load(path):
            self._compute()
            self.precompute_s = time.perf_counter() - t0
            self._save(path)
        else:
            self.load_s = time.perf_counter() - t0
        # CPU copy of the irradiance table (small) for the sky-ambient uniform.
        self.irradiance_host = self._read(self.irradiance)

    # --- residency ---------------------------------------------------------------------------------
    @classmethod
    def get(cls, ctx: moderngl.Context, params: AtmosphereParameters) -> "AtmosphereTables":
        current = cls._resident.get(ctx)
        if current is not None and current.params == params:
            return current
        if current is not None:
            current.release()
        tables = cls(ctx, params)
        cls._resident[ctx] = tables
        return tables

    def bind(self) -> None:
        for tex, unit in zip((self.transmittance, self.irradiance, self.scattering, self.single_mie),
                             TABLE_UNITS.values()):
            use_texture(tex, unit)

    def uniforms(self) -> dict:
        return {**self.params.uniforms(), **TABLE_UNITS}

    def release(self) -> None:
        for tex in (self.transmittance, self.irradiance, self.scattering, self.single_mie):
            tex.release()

    # --- textures ----------------------------------------------------------------------------------
    def _tex2d(self, size) -> moderngl.Texture:
        tex = self.ctx.texture(tuple(size), 4, dtype="f4")
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        tex.repeat_x = tex.repeat_y = False
        return tex

    def _tex3d(self, size) -> moderngl.Texture3D:
        tex = self.ctx.texture3d(tuple(size), 4, dtype="f4")
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        tex.repeat_x = tex.repeat_y = tex.repeat_z = False
        return tex

    @staticmethod
    def _read(tex) -> np.ndarray:
        data = np.frombuffer(tex.read(), dtype=np.float32)
        return data.reshape(tuple(reversed(tex.size)) + (4,)).copy()

    def arrays(self) -> dict[str, np.ndarray]:
        return {name: self._read(getattr(self, name))
                for name in ("transmittance", "irradiance", "scattering", "single_mie")}

    # --- disk cache --------------------------------------------------------------------------------
    def _load(self, path: Path) -> bool:
        try:
            with np.load(path) as data:
                arrays = {k: data[k] for k in ("transmittance", "irradiance", "scattering", "single_mie")}
        except (OSError, KeyError, ValueError):
            return False
        for name, array in arrays.items():
            tex = getattr(self, name)
            if array.shape != tuple(reversed(tex.size)) + (4,) or not np.all(np.isfinite(array)):
                return False
        for name, array in arrays.items():
            getattr(self, name).write(np.ascontiguousarray(array, dtype=np.float32).tobytes())
        self.from_cache = True
        try:
            os.utime(path)  # most recently used: the LRU eviction keys on the modification time
        except OSError:
            pass
        return True

    def _save(self, path: Path) -> None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(path.stem + f".{os.getpid()}.tmp.npz")
            np.savez(tmp, **self.arrays())
            os.replace(tmp, path)  # atomic: a concurrent reader sees the old file or the new one
            evict_least_recently_used(path.parent, cache_max_bytes(), keep=path)
        except OSError:
            pass  # a read-only cache only costs a recompute next time

    # --- GPU precompute ----------------------------------------------------------------------------
    def _compute(self) -> None:
        ctx, p, s = self.ctx, self.params, self.params.sizes
        programs = ProgramCache(ctx)
        common = p.uniforms()

        def stage(name: str, three_d: bool = False):
            defines = {"STAGE_" + name: 1, "DENSITY_SAMPLES": s.density_samples}
            if three_d:
                defines["STAGE_3D"] = 1
            prog = programs.compute(PRECOMPUTE_SHADER, defines)
            set_uniforms(prog, {**common, "u_transmittance_in": 0, "u_delta_irradiance_in": 1,
                                "u_delta_rayleigh_in": 2, "u_delta_mie_in": 3, "u_delta_multiple_in": 4,
                                "u_delta_density_in": 5})
            return prog

        def run(prog, size, three_d=False):
            if not three_d:
                prog.run(*_groups(size, (8, 8, 1)))
                ctx.memory_barrier()
                return
            # Slabs of 4 altitude rows: each dispatch stays short (a long one starves the render
            # process's progress messages, and the service takes silence for a hang).
            gx, gy, _ = _groups(size, (4, 4, 4))
            for z in range(0, size[2], 4):
                set_uniforms(prog, {"u_z_offset": z})
                prog.run(gx, gy, 1)
                ctx.memory_barrier()

        delta_irradiance = self._tex2d(s.irradiance)
        delta_rayleigh = self._tex3d(s.scattering)
        delta_mie = self._tex3d(s.scattering)
        delta_multiple = self._tex3d(s.scattering)
        delta_density = self._tex3d(s.scattering)
        for tex in (self.irradiance, self.scattering, self.single_mie):
            tex.write(np.zeros(tex.size[0] * tex.size[1] * (tex.size[2] if len(tex.size) == 3 else 1) * 4,
                               dtype=np.float32).tobytes())

        # 1. transmittance (optical depth)
        prog = stage("TRANSMITTANCE")
        self.transmittance.bind_to_image(0, read=False, write=True)
        run(prog, s.transmittance)
        use_texture(self.transmittance, 0)

        # 2. direct irradiance -> delta E (the irradiance table holds only the indirect part)
        prog = stage("DIRECT_IRRADIANCE")
        delta_irradiance.bind_to_image(0, read=False, write=True)
        run(prog, s.irradiance)

        # 3. single scattering
        prog = stage("SINGLE_SCATTERING", True)
        delta_rayleigh.bind_to_image(0, read=False, write=True)
        delta_mie.bind_to_image(1, read=False, write=True)
        run(prog, s.scattering, True)
        self.ctx.finish()
        self.scattering.write(delta_rayleigh.read())
        self.single_mie.write(delta_mie.read())

        density = stage("SCATTERING_DENSITY", True)
        indirect = stage("INDIRECT_IRRADIANCE")
        multiple = stage("MULTIPLE_SCATTERING", True)
        for order in range(2, s.orders + 1):
            use_texture(delta_irradiance, 1)
            use_texture(delta_rayleigh, 2)
            use_texture(delta_mie, 3)
            use_texture(delta_multiple, 4)
            # dJ of this order from dS(order-1) and the ground lit by dE(order-2)
            delta_density.bind_to_image(0, read=False, write=True)
            set_uniforms(density, {"u_order": order})
            run(density, s.scattering, True)
            # dE(order-1) from dS(order-1); E += dE
            delta_irradiance.bind_to_image(0, read=False, write=True)
            self.irradiance.bind_to_image(1, read=True, write=True)
            set_uniforms(indirect, {"u_order": order - 1})
            run(indirect, s.irradiance)
            # dS(order) = integral of T dJ;  S += dS / P_R(nu)
            use_texture(delta_density, 5)
            delta_multiple.bind_to_image(0, read=True, write=True)
            self.scattering.bind_to_image(1, read=True, write=True)
            set_uniforms(multiple, {"u_tail": int(order == s.orders and order >= 3)})
            run(multiple, s.scattering, True)
        self.ctx.finish()
        for tex in (delta_irradiance, delta_rayleigh, delta_mie, delta_multiple, delta_density):
            tex.release()
        programs._programs.clear()
