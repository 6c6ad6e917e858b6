"""The detail maps' inverse DFTs as GLSL made here (``generated/detail_fft.glsl``, included by
detail_rows.comp.glsl and detail_columns.comp.glsl; detail_synth.py registers it): ``detail_row`` and
``detail_column`` transform two rows or four columns of S = 1, 2, .. 512 points per invocation, each
point of them a vec4 or mat2x4 (DETAIL_C: two or four complex values) read by one load (no barrier: llvmpipe runs a
barrier's invocations as coroutines). On llvmpipe each storage load or store is a loop over the 8
lanes, its cost mostly per access, not per value (measured at 128²: dropping the columns' input load,
one of four accesses a point, saved 22 % of the pass; widening it to a vec4 cost 7 %): two transforms
an invocation take half the accesses, four columns in dvec4s (8 floats) a quarter.

Why generated: a DFT in a local array indexed by loop counters runs on llvmpipe as a search over the
array per access (~36 ns per radix-2 butterfly of 8 lanes); unrolled, each point is a variable of its
own and the twiddle factors are literals. Unrolled whole, though, a 128-point transform took llvmpipe's
LLVM 8 s to compile (3 min at 512). So a transform of S = RADIX · B points (B = 1, 2, .. 32) runs as two
unrolled steps through a scratch memory (the "four-step" FFT): with k = k1 + RADIX k2 and
x = x2 + B x1 (k1, x1 < RADIX; k2, x2 < B), w_N = e^{2πi / N},

    Z[k1][x2] = w_S^{k1 x2} Σ_k2 X[k1 + RADIX k2] w_B^{k2 x2}      (a B-point DFT per k1)
    y[x2 + B x1] = Σ_k1 Z[k1][x2] w_RADIX^{k1 x1}                 (one RADIX-point DFT per x2)

(w_S^{k x} splits so, w_S^{RADIX B k2 x1} = 1). Z sits at the places x2 + B k1 of the scratch
(the invocation's shared memory up to 128², else the output itself), the second step in place per x2.
The loops run to the uniform u_detail_radix (= RADIX), a bound the compiler cannot unroll; one
RADIX-point kernel serves every size, a B-point one per B up to the map's.
Compiled in 0.6 s at 128² (1.7 s at 512²) and ~20 % faster than unrolled whole (less spilled). The
kernels are radix 2, decimation in time: points d_k = X_{rev(k)} (k's bits reversed), joined in log2 n
stages, d_a, d_b ← d_a + w d_b, d_a − w d_b, w = e^{+2πi k / (2 span)}. The twiddles w_S^{k1 x2} are sines
of angles in [−π, π] (a float rounding). The result is Σ_k X_k e^{+2πi k x / S} (numpy's ifft with
norm="forward": no 1/S).
"""

from __future__ import annotations

import math

MAX_SIZE = 512  # water.py: the maps are 32² to 512²
RADIX = 16  # the largest transform unrolled whole (module docstring)


def _reversed(k: int, bits: int) -> int:
    return int(format(k, f"0{bits}b")[::-1], 2) if bits else 0


def _butterflies(size: int) -> list[str]:
    """The stages on the points d0 .. d{size − 1} (the input already in bit-reversed order):
    d_a, d_b ← d_a + w d_b, d_a − w d_b, w = e^{+2πi k / (2 span)} for the k-th pair of a block."""
    lines = []
    span = 1
    while span < size:
        for start in range(0, size, 2 * span):
            for k in range(span):
                a, b = f"d{start + k}", f"d{start + k + span}"
                angle = 2.0 * math.pi * k / (2 * span)
                if k == 0:
                    product = b
                elif 4 * k == 2 * span:  # w = i
                    product = f"detail_i({b})"
                else:
                    product = f"detail_mul(vec2({math.cos(angle):.9g}, {math.sin(angle):.9g}), {b})"
                lines.append(f"    t = {product}; {b} = {a} - t; {a} = {a} + t;")
        span *= 2
    return lines


def _kernel(size: int, load: str, store: str, place: str = "{k}", twiddle: str = "", indent: str = "    ") -> list[str]:
    """The statements of one unrolled ``size``-point inverse DFT: ``load`` the input {index} (an
    expression); ``store`` the output k (a statement of {at}, the output's ``place`` of {k}, and
    {value}, d{k} or, given ``twiddle`` (an expression of {k}), d{k} times it for k > 0)."""
    bits = int(math.log2(size))
    body = [f"DETAIL_C d{k} = {load.format(index=_reversed(k, bits))};" for k in range(size)]
    body += [line.strip() for line in _butterflies(size)]
    for k in range(size):
        value = f"detail_mul({twiddle.format(k=k)}, d{k})" if twiddle and k else f"d{k}"
        body.append(store.format(at=place.format(k=k), value=value) + ";")
    return [indent + line for line in body]


def _whole(name: str, size: int, params: str, load: str, store: str) -> str:
    """``name``_S: one unrolled S-point inverse DFT (S < RADIX)."""
    return "\n".join([f"void {name}_{size}(int size, {params}) {{", "    DETAIL_C t;", *_kernel(size, load, store), "}"])


def _step1(name: str, inner: int, params: str, load: str, scratch_store: str) -> str:
    """``name``_step_B: the first step for S = RADIX B, Z[k1][x2] = w_S^{k1 x2} Σ_k2 X[k1 + RADIX k2]
    w_B^{k2 x2} (a B-point DFT per k1) written at its place x2 + B k1."""
    step = _kernel(inner, load.replace("{index}", f"(k1 + {RADIX} * {{index}})"), scratch_store,
                   f"{{k}} + {inner} * k1", "detail_turn(k1 * {k}, size)", "        ")
    return "\n".join([f"void {name}_step_{inner}(int size, {params}) {{", "    DETAIL_C t;",
                      "    for (int k1 = 0; k1 < u_detail_radix; ++k1) {", *step, "    }", "}"])


def _transform(name: str, params: str, args: str, load: str, store: str, scratch_load: str, scratch_store: str) -> str:
    """``name``(size, ...): the inverse DFT of ``size`` points (the same for a whole work group): whole
    below RADIX; else the first step (a B-point DFT per k1, one function per B) and the second, one
    RADIX-point DFT per x2 < B whatever the size (y[x2 + B x1] = Σ_k1 Z[k1][x2] w_RADIX^{k1 x1}).
    ``load`` reads the input {index}; ``store`` writes {value} at the output's place {at};
    ``scratch_store`` and ``scratch_load`` write and read Z at its place {at}."""
    parts, cases, steps = [], [], []
    size = 1
    while size < RADIX:
        parts.append(_whole(name, size, params, load, store))
        cases.append(f"        case {size}: {name}_{size}(size, {args}); return;")
        size *= 2
    inner = 1
    while RADIX * inner <= MAX_SIZE:
        guard = f"#if DETAIL_N >= {RADIX * inner}"
        parts += [guard, _step1(name, inner, params, load, scratch_store), "#endif"]
        steps.append(f"{guard}\n        case {inner}: {name}_step_{inner}(size, {args}); break;\n#endif")
        inner *= 2
    step2 = _kernel(RADIX, scratch_load.replace("{at}", "x2 + inner * {index}"), store, "x2 + inner * {k}", "", "        ")
    parts.append("\n".join([
        f"void {name}(int size, {params}) {{", "    switch (size) {", *cases, "    }",
        f"    int inner = size / {RADIX};", "    switch (inner) {", *steps, "    }", "    DETAIL_C t;",
        "    for (int x2 = 0; x2 < inner; ++x2) {", *step2, "    }", "}"]))
    return "\n".join(parts)


HEAD = """uniform int u_detail_radix;  // RADIX (detail_fft.py): a loop bound the compiler cannot unroll
vec2 detail_mul(vec2 a, vec2 b) { return vec2(a.x * b.x - a.y * b.y, a.x * b.y + a.y * b.x); }
vec4 detail_mul(vec2 a, vec4 b) { return vec4(detail_mul(a, b.xy), detail_mul(a, b.zw)); }  // a pair
mat2x4 detail_mul(vec2 a, mat2x4 b) { return mat2x4(detail_mul(a, b[0]), detail_mul(a, b[1])); }  // four
vec2 detail_i(vec2 b) { return vec2(-b.y, b.x); }  // i b
vec4 detail_i(vec4 b) { return vec4(-b.y, b.x, -b.w, b.z); }
mat2x4 detail_i(mat2x4 b) { return mat2x4(detail_i(b[0]), detail_i(b[1])); }
vec2 detail_turn(int j, int n) {  // e^{2πi j / n}, 0 <= j < n, its angle taken in [−π, π]
    float angle = 6.28318531 * float(2 * j > n ? j - n : j) / float(n);
    return vec2(cos(angle), sin(angle));
}"""


def fft_glsl() -> str:
    """The generated file: ``detail_row`` (DETAIL_ROWS: a row's spectrum at detail_grid[spectrum ..]
    to its inverse DFT at detail_grid[along ..]) and ``detail_column`` (DETAIL_COLUMNS: the columns x
    .. x + 3 of a level's grid at detail_grid[along ..], x a multiple of 4, as one quad (mat2x4: each
    point's four complex values, one load, ``detail_quad``) to the level's texels (sx, sy, sx² +
    removed_x, sy² + removed_y) at detail_texels[texel + y S] and the next three, texel the column x's
    first; Z between the steps through ``detail_z``: shared memory or the texels)."""
    return "\n".join([
        HEAD,
        "#ifdef DETAIL_ROWS",
        "#define DETAIL_C vec4",
        _transform("detail_row", "int spectrum, int a, int b", "spectrum, a, b", "detail_grid4[(spectrum >> 1) + {index}]",
                   "detail_row_store({at}, a, b, {value})", "detail_z({at}, a, b)", "detail_z({at}, a, b, {value})"),
        "#endif",
        "#ifdef DETAIL_COLUMNS",
        "#define DETAIL_C mat2x4",
        _transform("detail_column", "int along, int x, int texel, vec2 removed", "along, x, texel, removed",
                   "detail_quad(along + ({index}) * size + x)",
                   "detail_column_store(texel + ({at}) * size, {value}, removed)", "detail_z({at}, texel, size)",
                   "detail_z({at}, texel, size, {value})"),
        "#endif", ""])
