"""A-posteriori error indicator and the snapshot-count rule."""

import jax.numpy as jnp

import jaxbelt as jb
from jaxbelt.rom import collect_first_order, fit_dmd, fit_reduced_pod_ranks, parameters, rmse, tracer_operator
from jaxbelt.rom.indicator import residual_indicator, snapshot_count


def test_indicator_is_zero_on_a_full_trajectory_and_tracks_reduced_errors():
    m = jb.load_model("two-roller-1d-train1")
    st0 = jb.initial_state(m)
    _, Zp, Zq = collect_first_order(m, 150)
    # a full-order trajectory has zero residual
    ind = residual_indicator(m, Zq.T, stride=10)
    assert float(jnp.max(ind["residual_mm"])) < 1e-10
    _, ref = jb.simulate(m, n_steps=306)  # whole checkpoint chunks: one compiled step
    true, est = [], []
    # one projection at r = 20, truncated (= a fit at each rank: test_rom_ranks)
    roms = fit_reduced_pod_ranks(m, jnp.concatenate([Zp, Zq], axis=1), (5, 10, 20))
    for r in (5, 10, 20):
        rom = roms[r]
        xi0 = rom.project(m, st0)
        out = rom.run(xi0, parameters(m), 306)
        err_t = jnp.sqrt(jnp.mean((ref.tracer_u - out["tracer_u"]) ** 2, axis=1)) * 1e3
        ind = residual_indicator(m, rom.fields(jnp.concatenate([xi0[None], out["xi"]])), stride=10)
        true.append(float(jnp.max(err_t)))
        est.append(float(ind["estimate_mm"][-1]))
    # ranks the models as their true errors do, and errs on the safe side
    assert true[0] > true[1] > true[2] and est[0] > est[1] > est[2]
    assert all(e > t for e, t in zip(est, true))
    assert est[2] < 0.2 and est[0] > 0.2  # flags the 5-mode model (true error > 0.02 mm) only


def test_snapshot_rule_stops_when_new_data_are_predicted():
    m = jb.load_model("two-roller-1d-train1")
    C = tracer_operator(m)
    Cz = jnp.concatenate([C, jnp.zeros_like(C)], axis=1)

    def fit_predict(Z, n):
        return fit_dmd(Z).predict(Z[:, -1], n, observe=Cz)

    res = snapshot_count(m, fit_predict, chunk=50, max_steps=600)
    assert res["converged"]
    assert res["history"][-1][1] < 0.1 * 0.02
    assert all(e >= 0.002 for _, e in res["history"][:-1])  # stopped at the first chunk that passed
    # a model trained on that many snapshots predicts the next 200 steps within tolerance
    Z = res["Z"]
    state = jb.simulate(m, n_steps=res["n_steps"])[0]
    _, tr = jb.simulate(m, state=state, n_steps=200)
    pred = fit_dmd(Z).predict(Z[:, -1], 200, observe=Cz)
    assert float(rmse(tr.tracer_u, pred)) * 1e3 < 0.02
