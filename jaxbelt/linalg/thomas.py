"""Block Thomas elimination of a block-tridiagonal matrix, and its sweeps rearranged along the
chains of dependent blocks that the belt's roller columns cut the interior into
(:class:`ChainedThomasFactors`). The interior solver of :mod:`jaxbelt.linalg.bordered` on a CPU
(the sequential ``lax.scan`` there; block cyclic reduction, :mod:`jaxbelt.linalg.cyclic_reduction`,
on accelerators)."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax


class ThomasFactors(eqx.Module):
    """Block Thomas factors: inverse pivot blocks, ``Ĉ = den⁻¹ U`` and the sub-diagonal blocks."""

    inv: jax.Array
    C_hat: jax.Array
    L: jax.Array


def thomas_factor(diag, lower, upper, rhs=None):
    """Block Thomas factors; with ``rhs`` (m, b, k) also solves for it in the same sweep and
    returns ``(factors, solution)`` (one scan instead of two for the border columns)."""
    diag, lower, upper = jnp.asarray(diag), jnp.asarray(lower), jnp.asarray(upper)
    rhs = None if rhs is None else jnp.asarray(rhs)
    b = diag.shape[1]
    eye = jnp.eye(b, dtype=diag.dtype)
    lower = lower.at[0].set(0.0)
    k = 0 if rhs is None else rhs.shape[2]
    r = jnp.zeros((diag.shape[0], b, 0), diag.dtype) if rhs is None else rhs

    def forward(carry, blk):
        c_prev, y_prev = carry
        a, l, u, rr = blk
        inv = jnp.linalg.solve(a - l @ c_prev, eye)
        c, y = inv @ u, inv @ (rr - l @ y_prev)
        return (c, y), (inv, c, y)

    init = (jnp.zeros((b, b), diag.dtype), jnp.zeros((b, k), diag.dtype))
    _, (inv, C_hat, ys) = lax.scan(forward, init, (diag, lower, upper, r))
    F = ThomasFactors(inv, C_hat, lower)
    if rhs is None:
        return F

    def backward(x_next, blk):
        c, y = blk
        x = y - c @ x_next
        return x, x

    _, xs = lax.scan(backward, jnp.zeros((b, k), diag.dtype), (C_hat, ys), reverse=True)
    return F, xs


def thomas_apply(F: ThomasFactors, rhs):
    """Forward sweep ``y_i = den_i⁻¹ (r_i - L_i y_{i-1})``, backward ``x_i = y_i - Ĉ_i x_{i+1}``."""

    def forward(y_prev, blk):
        inv_i, l, r = blk
        y = inv_i @ (r - l @ y_prev)
        return y, y

    _, ys = lax.scan(forward, jnp.zeros_like(rhs[0]), (F.inv, F.L, rhs))

    def backward(x_next, blk):
        c, y = blk
        x = y - c @ x_next
        return x, x

    _, xs = lax.scan(backward, jnp.zeros_like(ys[0]), (F.C_hat, ys), reverse=True)
    return xs


class ChainedThomasFactors(eqx.Module):
    """Block Thomas factors rearranged along their chains of dependent blocks.

    A block ``i`` whose couplings ``L_i`` and ``U_i`` both vanish breaks the sweeps' chain of
    dependencies: its forward value does not need block ``i - 1``'s and its backward value does
    not need block ``i + 1``'s (``Ĉ_i = 0``). The belt's roller columns are such blocks — their
    rows are no-slip constraints, coupled only to the roller unknowns — so the interior falls
    apart into one chain per free span (each led, forward, by the roller column before it and,
    backward, by the one after it) and single roller columns. Both sweeps then run all chains at
    once, as long as the longest span, and the single blocks as one batched product: on
    ``three-roller-t72`` 37 dependent steps per sweep instead of 103 — the same arithmetic, ~35 %
    less time on a CPU. Built by :func:`chain_thomas` from static break positions; the result
    equals :func:`thomas_apply`'s (``tests/integration/integrators/test_kept_interior.py``).

    The forward sweep ``y_i = den_i⁻¹ (r_i - L_i y_{i-1})`` takes one of two forms.

    * **Banded coupling** (``band = w``, the caller's guarantee that every ``L_i`` vanishes
      beyond ``w`` diagonals off its main one: ``2 p - 1`` for a block-tridiagonal coupling of
      ``p × p`` node blocks, the belt's 3 in 2D, 0 in 1D): ``L_i`` is kept as its ``2 w + 1``
      diagonals and applied as shifted products inside the scan, then ``den_i⁻¹``. One dense
      block streamed per step and block, where the dense form streams two, and the chained
      factors a third smaller; with several right-hand sides one dense product per block fewer,
      which sweeps of several columns at once gain most from (forward-mode tangents; the exact
      mode's tilt columns where it sweeps them). With one right-hand side the step's two
      dependent operations instead of one cost about what the bytes save, and the
      factorisation-reuse solver keeps the dense form (both timed in
      ``benchmarks/step_profile.py``).
    * **Dense coupling** (``band = None``): ``y_i = g_i - P_i y_{i-1}`` with ``g_i = den_i⁻¹ r_i``
      (all blocks at once, one batched product outside the scan) and ``P_i = den_i⁻¹ L_i``
      (formed once with the factors): one dependent block product per step instead of two.

    Blocks are moved between the chains' and the natural order by gathers
    with static index tables (a gather's transpose is the scatter-add reverse mode needs; a
    scatter in the forward pass is slow on a CPU).

    **No padding.** A sweep streams its factor blocks from memory once per solve, and that,
    not the chain's latency, sets its pace on a CPU: a dependent block product inside the scan
    takes about twice as long with its blocks streamed as with the same blocks in cache, and
    two-ended sweeps (twice the chains, half the steps) take as long as one-ended ones. The chains are therefore sorted by length
    and each sweep runs in *phases*, one ``lax.scan`` per distinct length, the finished chains
    dropped from the carry — instead of padding every chain with zero blocks to the longest (a
    quarter of the blocks streamed on the default scene were zeros).

    **Fields:** per forward phase ``f_inv`` (steps, chains, b, b) and either ``f_P`` (the same
    shape; dense coupling) or ``f_L`` (steps, chains, 2 w + 1, b), the diagonals of ``L_i``
    (``[d + w, j] = L_i[j, j + d]``; banded coupling, else ``()``); single blocks ``s_inv``; per
    backward phase ``b_C``; ``layout`` the static index tables; ``band`` ``w`` or ``None``."""

    f_inv: tuple
    f_P: tuple
    s_inv: jax.Array
    b_C: tuple
    layout: tuple = eqx.field(static=True)  # (f_phases, singles, b_phases, m): block-index tables
    f_L: tuple = ()
    band: int | None = eqx.field(static=True, default=None)


def elimination_chains(m: int, breaks, reverse: bool):
    """The chains of dependent blocks of an ``m``-block interior cut at the ``breaks`` (bool per
    block): lists of block indices in sweep order (``reverse``: the backward sweep's)."""
    order = range(m - 1, -1, -1) if reverse else range(m)
    out, cur = [], []
    for i in order:
        if breaks[i] and cur:
            out.append(cur)
            cur = []
        cur.append(i)
    out.append(cur)
    return out


def _phases(chains):
    """The chains (longest first) as phases: one (steps, chains) block-index table per distinct
    chain length, each holding the steps of the chains still running."""
    chains = sorted(chains, key=len, reverse=True)
    lengths = sorted({len(c) for c in chains}, reverse=True)
    out, t0 = [], 0
    for ln in reversed(lengths):  # ascending: the phase ends when the shortest running chain does
        running = [c for c in chains if len(c) >= ln]
        if ln > t0:
            out.append(tuple(tuple(c[t] for c in running) for t in range(t0, ln)))
        t0 = ln
    return tuple(out)


def take_blocks(a, index):
    """``a[index]`` for a static integer ``index`` of any shape, gathered through the flattened
    index and reshaped: a product of two arrays gathered with a 2-D index, batched by ``vmap``,
    fails XLA's HLO verifier on the CPU (jax 0.10.2); the flat gather does not."""
    index = np.asarray(index, int)
    return a[index.reshape(-1)].reshape(index.shape + a.shape[1:])


def chain_thomas(F: ThomasFactors, breaks, band: int | None = None) -> ChainedThomasFactors:
    """Rearrange ``F`` along its chains (:class:`ChainedThomasFactors`). ``breaks`` (m,) static
    booleans: ``True`` where the block's ``L_i`` and ``U_i`` are zero (the caller's guarantee;
    e.g. the belt's roller columns). ``band``: ``w`` where every ``L_i`` is zero beyond ``w``
    diagonals off its main one (the caller's guarantee: entries beyond are dropped), else
    ``None`` (dense)."""
    m = F.inv.shape[0]
    breaks = [bool(x) for x in breaks]
    fw = elimination_chains(m, breaks, reverse=False)
    singles = tuple(c[0] for c in fw if len(c) == 1)
    fw = [c for c in fw if len(c) > 1]
    bw = [c for c in elimination_chains(m, breaks, reverse=True) if len(c) > 1]
    f_ph, b_ph = _phases(fw), _phases(bw)
    f_inv = tuple(take_blocks(F.inv, t) for t in f_ph)
    b_C = tuple(take_blocks(F.C_hat, t) for t in b_ph)
    s_inv = F.inv[np.asarray(singles, int)]
    if band is None:
        f_P = tuple(fi @ take_blocks(F.L, t) for fi, t in zip(f_inv, f_ph))
        return ChainedThomasFactors(f_inv, f_P, s_inv, b_C, (f_ph, singles, b_ph, m))
    f_L = tuple(band_diagonals(take_blocks(F.L, t), band) for t in f_ph)
    return ChainedThomasFactors(f_inv, (), s_inv, b_C, (f_ph, singles, b_ph, m), f_L, int(band))


def band_diagonals(L, w: int):
    """The ``2 w + 1`` diagonals of blocks ``L`` (..., b, b): (..., 2 w + 1, b) with
    ``[d + w, j] = L[j, j + d]`` (zero where ``j + d`` falls outside the block)."""
    b = L.shape[-1]
    j = np.arange(b)
    return jnp.stack([jnp.where((j + d >= 0) & (j + d < b), L[..., j, np.clip(j + d, 0, b - 1)], 0.0)
                      for d in range(-w, w + 1)], axis=-2)


def band_times(Ld, y, w: int):
    """``L y`` for ``L`` given by its diagonals ``Ld`` (c, 2 w + 1, b) (:func:`band_diagonals`)
    and ``y`` (c, b, k): ``2 w + 1`` shifted elementwise products, which XLA fuses into one loop."""
    b = y.shape[1]
    yp = jnp.pad(y, ((0, 0), (w, w), (0, 0)))
    out = Ld[:, w, :, None] * y
    for d in range(-w, w + 1):
        if d:
            out = out + Ld[:, d + w, :, None] * yp[:, w + d: w + d + b]
    return out


def _flat(phases):
    return np.concatenate([np.asarray(t).reshape(-1) for t in phases]) if phases else np.zeros(0, int)


def _chain_gathers(layout):
    """Static gather tables of a chained layout: ``fwd`` takes the natural order out of
    ``concat(forward phases (flattened), single blocks)``; ``bwd`` takes it out of
    ``concat(backward phases (flattened), forward values)`` — a block in no backward chain keeps
    its forward value."""
    f_ph, singles, b_ph, m = layout
    fi, bi = _flat(f_ph), _flat(b_ph)
    fwd = np.full(m, -1)
    fwd[fi] = np.arange(fi.size)
    fwd[np.asarray(singles, int)] = fi.size + np.arange(len(singles))
    assert (fwd >= 0).all(), "every block is in a forward chain or single"
    bwd = np.arange(m) + bi.size
    bwd[bi] = np.arange(bi.size)
    return fwd, bwd


def _scan_phases(step, inputs):
    """``lax.scan(step)`` along the chains, phase by phase: ``inputs`` per phase a tuple of
    (steps, chains, ...) arrays, the last the values (steps, chains, b, k) whose shape the carry
    takes; the carry cut to the chains still running, zero at the start. The values of every
    phase, flattened."""
    out, carry = [], jnp.zeros(inputs[0][-1].shape[1:], inputs[0][-1].dtype) if inputs else None
    for xs in inputs:
        carry, vs = lax.scan(step, carry[: xs[-1].shape[1]], xs)
        out.append(vs.reshape((-1,) + vs.shape[2:]))
    return out


def _sweep(mats, values):
    """One sweep ``v_t = values_t - mats_t v_{t-1}`` along the chains (:func:`_scan_phases`; per
    phase (steps, chains, b, b) and (steps, chains, b, k))."""

    def step(prev, blk):
        a, v = blk
        v = v - a @ prev
        return v, v

    return _scan_phases(step, list(zip(mats, values)))


def _forward(F: ChainedThomasFactors, values):
    """The forward sweep ``y_t = den_t⁻¹ (r_t - L_t y_{t-1})`` along the chains, ``values`` the
    right-hand side's blocks per phase: with banded ``L`` (shifted products, then ``den⁻¹``) or
    as ``g_t - P_t y_{t-1}`` (:class:`ChainedThomasFactors`); the values of every phase, flattened."""
    if F.band is None:
        return _sweep(F.f_P, [inv @ r for inv, r in zip(F.f_inv, values)])  # den⁻¹ r of each phase, batched

    def step(prev, blk):
        inv, Ld, r = blk
        y = inv @ (r - band_times(Ld, prev, F.band))
        return y, y

    return _scan_phases(step, list(zip(F.f_inv, F.f_L, values)))


def chained_thomas_apply(F: ChainedThomasFactors, rhs):
    """:func:`thomas_apply` along the chains; ``rhs`` (m, b, k)."""
    f_ph, singles, b_ph, _ = F.layout
    fwd, bwd = _chain_gathers(F.layout)
    chains = _forward(F, [take_blocks(rhs, t) for t in f_ph])
    y = jnp.concatenate(chains + [F.s_inv @ rhs[np.asarray(singles, int)]])[fwd]  # (m, b, k) natural order
    xs = _sweep(F.b_C, [take_blocks(y, t) for t in b_ph])
    return jnp.concatenate(xs + [y])[bwd]


def _phase_chains(phases):
    """The chains of a phase layout (:func:`_phases`), each its blocks in sweep order, in the
    phases' chain order (longest first)."""
    if not phases:
        return []
    chains = [[] for _ in range(len(phases[0][0]))]
    for table in phases:
        for row in table:
            for q, blk in enumerate(row):
                chains[q].append(blk)
    return chains


def _columns_per_chain(chains, support):
    """``(table (chains, k_max), back (chains, k))``: per chain the columns whose ``support``
    (per column, a set of blocks) meets it, padded with the zero column ``k``; and where each
    column sits in its chain's row (``k_max``: not there, read as zero)."""
    k = len(support)
    cols = [[c for c in range(k) if support[c] & set(chain)] for chain in chains]
    k_max = max([len(c) for c in cols] + [1])
    table = np.full((len(chains), k_max), k)
    back = np.full((len(chains), k), k_max)
    for q, cs in enumerate(cols):
        table[q, :len(cs)] = cs
        back[q, cs] = np.arange(len(cs))
    return table, back


def _select_columns(values, table):
    """``values`` (steps, chains, b, k) → (steps, chains, b, k_max): each chain's columns of
    ``table`` (index ``k``: a zero column)."""
    z = jnp.concatenate([values, jnp.zeros(values.shape[:-1] + (1,), values.dtype)], axis=-1)
    return jnp.take_along_axis(z, jnp.asarray(table)[None, :, None, :], axis=-1)


def chained_thomas_apply_sparse(F: ChainedThomasFactors, rhs, support):
    """:func:`chained_thomas_apply` for a right-hand side whose column ``c`` is zero off the blocks
    ``support[c]`` (static; the caller's guarantee): each chain's sweeps carry only the columns
    that can be non-zero on it. On the belt the exact mode's tilt columns (where it sweeps them) live on one roller's
    columns each, and a free span's forward sweep sees only the roller before it, its backward
    sweep the rollers on both sides: on a three-roller belt half of the columns' sweeps are zero
    and skipped. The result equals :func:`chained_thomas_apply`'s (the skipped values are exact
    zeros)."""
    f_ph, singles, b_ph, m = F.layout
    k = rhs.shape[-1]
    support = [set(int(i) for i in sup) for sup in support]
    fwd, bwd = _chain_gathers(F.layout)
    f_chains = _phase_chains(f_ph)
    f_table, f_back = _columns_per_chain(f_chains, support)
    # where the forward values can be non-zero: the chains a column's support meets, and its single blocks
    y_support = [set().union(*[ch for ch in f_chains if sup & set(ch)]) | (sup & set(singles)) for sup in support]
    b_chains = _phase_chains(b_ph)
    b_table, b_back = _columns_per_chain(b_chains, y_support)

    def restricted(values_per_phase, table):
        return [_select_columns(v, table[: v.shape[1]]) for v in values_per_phase]

    def widen(flat_per_phase, phases, back):
        """Per phase the (steps chains, b, k_max) values back to all k columns (zero elsewhere)."""
        out = []
        for v, t in zip(flat_per_phase, phases):
            steps, n = len(t), len(t[0])
            v = v.reshape((steps, n) + v.shape[1:])
            out.append(_select_columns(v, back[:n]).reshape((steps * n,) + v.shape[2:-1] + (k,)))
        return out

    chains = _forward(F, restricted([take_blocks(rhs, t) for t in f_ph], f_table))
    y = jnp.concatenate(widen(chains, f_ph, f_back) + [F.s_inv @ rhs[np.asarray(singles, int)]])[fwd]
    xs = _sweep(F.b_C, restricted([take_blocks(y, t) for t in b_ph], b_table))
    return jnp.concatenate(widen(xs, b_ph, b_back) + [y])[bwd]
