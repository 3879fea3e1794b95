"""Belt states (:mod:`jaxbelt.state`): carried from one grid onto another."""

import dataclasses

import numpy as np

import jaxbelt as jb
from jaxbelt.accuracy import refine
from jaxbelt.state import initial_state, prolongate

SCENE = "two-roller-steered"


def test_prolongate_carries_a_state_onto_another_grid():
    """:func:`jaxbelt.state.prolongate`: onto the same grid it is the identity; onto the grid with
    twice the columns and rows, the shared nodes keep their values, the new ones are the means of
    their neighbours, and the element masses keep their relative deviation (a state with random
    fields: the carrying is linear interpolation, whatever the state)."""
    scene = jb.load_scene(SCENE)
    model = jb.build_model(scene)
    rng = np.random.default_rng(3)
    s0 = initial_state(model)
    state = dataclasses.replace(s0, u=s0.u + 1e-5 * rng.standard_normal(s0.u.shape),
                                u_dot=1e-4 * rng.standard_normal(s0.u.shape),
                                m_e=np.asarray(model.m_e0) * (1.0 + 1e-3 * rng.standard_normal(model.m_e0.shape)))
    same = prolongate(state, model, model)
    for a, b in ((same.u, state.u), (same.u_dot, state.u_dot), (same.m_e, state.m_e)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-12, atol=1e-18)
    fine = jb.build_model(refine(scene, n_xi=2.0, n_eta=2.0))
    assert fine.x.shape[0] == 2 * model.x.shape[0] and fine.n_eta == 2 * model.n_eta - 1
    f = prolongate(state, model, fine)
    u, uf = np.asarray(state.u).reshape(len(model.x), model.n_eta, 2), \
        np.asarray(f.u).reshape(len(fine.x), fine.n_eta, 2)
    np.testing.assert_allclose(uf[::2, ::2], u, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(uf[1::2, ::2], 0.5 * (u + np.roll(u, -1, axis=0)), rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(uf[::2, 1::2], 0.5 * (u[:, :-1] + u[:, 1:]), rtol=1e-9, atol=1e-15)
    rel, rel_f = np.asarray(state.m_e) / np.asarray(model.m_e0), np.asarray(f.m_e) / np.asarray(fine.m_e0)
    assert abs(np.mean(rel_f) - np.mean(rel)) < 1e-12 + 1e-3 * np.ptp(rel)
