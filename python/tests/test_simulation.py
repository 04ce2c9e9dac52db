"""Simulations from NumPy arrays: views, scripted pins and obstacles, solvers by name."""
import gc
import math

import numpy as np
import pytest

import mgcloth
from conftest import hanging


def test_drape_in_five_lines():
    V, F = mgcloth.grid(1.0, 1.0, 100)
    sim = mgcloth.Simulation(cloths=[mgcloth.Cloth(V, F, pins=[0, 9])],
                             obstacles=[mgcloth.Sphere(0.3, center=(0.5, 0.5, -0.5))], dt=1 / 30, rel_grad=1e-3)
    for _ in range(10):
        sim.step()
    assert sim.x.shape == (100, 3) and np.isfinite(sim.x).all()
    assert sim.frame == 10 and sim.time == pytest.approx(1 / 3)
    assert sim.x[:, 2].min() < -0.05  # it fell
    assert np.abs(sim.x[[0, 9]] - V[[0, 9]]).max() < 0.01  # but hangs from its pins


def test_positions_are_live_read_only_views_that_keep_the_simulation_alive(small_grid):
    V, F = small_grid
    sim = hanging(V, F)
    x, v = sim.x, sim.velocities(0)
    assert x.shape == (64, 3) and x.dtype == np.float64 and not x.flags.writeable
    assert x.base is sim  # a view onto the simulator's state, not a copy
    with pytest.raises(ValueError):
        x[0, 0] = 1.0
    start = x.copy()
    sim.step()
    assert not np.array_equal(x, start)  # the view follows the simulation
    assert np.array_equal(x, sim.positions("cloth0")) and np.array_equal(x, sim.positions(np.int64(0)))
    assert np.abs(v).max() > 0
    del sim
    gc.collect()
    assert np.isfinite(x).all()  # still valid: the view holds the simulation
    assert np.array_equal(mgcloth.Mesh(V, F).triangles, F)


def test_a_scripted_pin_animation_moves_the_cloth(small_grid):
    V, F = small_grid
    still, moved = hanging(V, F), hanging(V, F)
    assert list(moved.pinned_vertices()) == [0, 7]
    targets = moved.pin_targets()
    np.testing.assert_array_equal(targets, V[[0, 7]])
    for _ in range(8):
        targets = targets + [0.02, 0.0, 0.01]  # 0.6 m/s along x, 0.3 m/s up
        moved.set_pin_targets(targets)
        moved.step()
        still.step()
        np.testing.assert_array_equal(moved.pin_targets(), targets)
        assert np.abs(moved.x[[0, 7]] - targets).max() < 2e-3
    shift = moved.x.mean(axis=0) - still.x.mean(axis=0)
    assert shift[0] > 0.1 and shift[2] > 0.03  # the whole cloth followed the pins


def test_obstacles_can_be_moved_between_steps(small_grid):
    V, F = small_grid
    sim = hanging(V, F, obstacles=[mgcloth.Sphere(0.1, center=(0.25, 0.25, -0.2), name="ball")])
    for f in range(6):
        sim.set_obstacle_pose("ball", position=(0.25, 0.25, -0.2 + 0.06 * (f + 1)), rotation_deg=(0, 0, 10 * f))
        sim.step()
    position, rotation = sim.obstacle_pose("ball")
    np.testing.assert_allclose(position, [0.25, 0.25, 0.16], atol=1e-12)
    np.testing.assert_allclose(rotation, [[np.cos(np.pi / 3.6), -np.sin(np.pi / 3.6), 0],
                                          [np.sin(np.pi / 3.6), np.cos(np.pi / 3.6), 0], [0, 0, 1]], atol=1e-12)
    middle = np.argmin(((sim.x[:, :2] - 0.25) ** 2).sum(axis=1))
    assert sim.x[middle, 2] > 0.25  # lifted by the sphere, whose top is at 0.26
    with pytest.raises(mgcloth.InputError, match='no obstacle named "bal"'):
        sim.set_obstacle_pose("bal", position=(0, 0, 0))
    with pytest.raises(mgcloth.InputError, match="rotation: not a rotation matrix"):
        sim.set_obstacle_pose(0, rotation=np.diag([1.0, 1.0, -1.0]))


def test_every_solver_runs_by_name(small_grid):
    V, F = small_grid
    for name in mgcloth.solver_names():
        # Two levels for the multilevel solvers on this small mesh.
        try:
            sim = hanging(V, F, solver=name, rel_grad=1e-3, hierarchy={"max_coarse_vertices": 20,
                                                                         "min_coarse_vertices": 10},
                          energy_form="projective" if name.startswith("pd-") else "elastic")
            stats = sim.step(2)
        except mgcloth.Error as e:
            # The CUDA solver without a GPU (or in a build without CUDA) says so.
            assert name == "fmg-cuda" and ("GPU" in str(e) or "CUDA" in str(e)), f"{name}: {e}"
            continue
        assert [s.solver for s in stats] == [name, name]
        assert np.isfinite(sim.x).all(), name
    with pytest.raises(mgcloth.InputError, match=r'solver.name: unknown value "nope" \(expected one of: fmg'):
        hanging(V, F, solver="nope")
    # The scene chooses the energy form; the PD local/global iterations minimize only the projective one.
    with pytest.raises(mgcloth.InputError, match=r'solver "pd-fmg" cannot minimize the elastic energy form'):
        hanging(V, F, solver="pd-fmg")


def test_traces_come_back_as_arrays(small_grid):
    V, F = small_grid
    sim = hanging(V, F, trace=True)
    (stats,) = sim.step()
    t = stats.trace
    assert set(t) == {"iteration", "energy", "grad_norm", "wall_ms", "step"}
    assert len(t["energy"]) == stats.iterations + 1 and t["iteration"][0] == 0
    assert t["energy"][-1] == stats.energy and t["energy"][-1] <= t["energy"][0]
    assert hanging(V, F).step()[0].trace is None


def test_scene_dict_with_obstacle_objects_and_resolved_scene(small_grid):
    V, F = small_grid
    scene = {"time_step": 0.02, "substeps": 2,
             "cloths": [mgcloth.Cloth(V, F, name="sheet", material="silk")],
             "obstacles": [mgcloth.Plane(point=(0, 0, -0.1), friction=0.5), {"shape": {"type": "box"}, "position": [2, 0, 0]}]}
    sim = mgcloth.Simulation(scene, threads=1, rel_grad=1e-3)
    assert sim.dt == 0.02 and sim.step_size == 0.01
    assert sim.cloth_names == ["sheet"] and sim.obstacle_names == ["obstacle0", "obstacle1"]
    stats = sim.step()
    assert [s.step for s in stats] == [1, 2]
    resolved = sim.scene
    assert resolved["cloths"][0]["material"]["preset"] == "silk"
    assert resolved["cloths"][0]["mesh"] == {"arrays": {"vertices": 64, "triangles": len(F)}}
    assert resolved["obstacles"][0]["friction"] == 0.5
    assert sim.masses().sum() == pytest.approx(0.25 * 0.08)  # silk: 80 g/m²


def test_the_generated_body_stands_under_a_cloth_dropped_on_its_shoulders():
    # A 0.5 m square (head hole not needed: it falls on the head and shoulders) on a coarse standing mannequin.
    V, F = mgcloth.grid(0.5, 0.5, 100)
    V[:, :2] -= 0.25
    V[:, 2] = 1.8
    body = mgcloth.Body(1.75, resolution=0.03, name="body", friction=0.4)
    sim = mgcloth.Simulation(cloths=[mgcloth.Cloth(V, F, name="sheet")], obstacles=[body], cloth_contact={},
                             dt=1 / 30, rel_grad=1e-3, threads=1)
    for _ in range(8):
        stats = sim.step()
        assert all(s.intersections == 0 and s.obstacle_rounds == 0 for s in stats)  # it stands: no re-solves
    assert sim.obstacle_names == ["body"]
    assert sim.x[:, 2].max() > 1.70  # caught by the head (1.75 m) rather than falling through
    assert sim.scene["obstacles"][0]["body"]["height"] == 1.75
    assert "walk" not in sim.scene["obstacles"][0]["body"]
    with pytest.raises(mgcloth.InputError, match="body.height"):
        mgcloth.Simulation(cloths=[mgcloth.Cloth(V, F)], obstacles=[mgcloth.Body(3.0)], cloth_contact={})


def test_a_mesh_obstacle_from_an_obj_file_holds_the_cloth(tmp_path):
    # A 0.3 m square plate in z = 0 (two triangles, no thickness); a cloth falls onto it through cloth contact.
    (tmp_path / "plate.obj").write_text("v -0.15 -0.15 0\nv 0.15 -0.15 0\nv 0.15 0.15 0\nv -0.15 0.15 0\n"
                                        "f 1 2 3\nf 1 3 4\n")
    V, F = mgcloth.grid(0.2, 0.2, 100)
    V[:, :2] -= 0.1
    V[:, 2] = 0.03
    sim = mgcloth.Simulation(cloths=[mgcloth.Cloth(V, F, name="sheet")],
                             obstacles=[mgcloth.MeshObstacle(tmp_path / "plate.obj", name="plate", friction=0.5)],
                             cloth_contact={}, dt=1 / 30, rel_grad=1e-3, threads=1)
    for _ in range(10):
        stats = sim.step()
        assert all(s.intersections == 0 for s in stats)
    assert sim.obstacle_names == ["plate"]
    assert sim.x[:, 2].min() > 0.0  # on the plate, not through it
    assert sim.x[:, 2].max() < 0.01
    assert sim.scene["obstacles"][0]["mesh"] == str(tmp_path / "plate.obj")
    with pytest.raises(mgcloth.InputError, match="cloth_contact"):
        mgcloth.Simulation(cloths=[mgcloth.Cloth(V, F)], obstacles=[mgcloth.MeshObstacle(tmp_path / "plate.obj")])


def test_a_velocity_tolerance_stops_each_step_by_its_estimate(small_grid):
    # Each step ends once the solver's estimate of the largest per-vertex velocity error is within the tolerance,
    # which StepStats reports; a single-level smoother, whose steps cannot show its error, is refused it.
    V, F = small_grid
    sim = hanging(V, F, solver="fmg", rel_grad=0.0, velocity_tol=1e-3)
    for s in sim.step(3):
        assert s.status == "converged" and s.velocity_error <= 1e-3
    with pytest.raises(mgcloth.InputError, match="velocity_tol"):
        hanging(V, F, solver="gs-chebyshev", velocity_tol=1e-3).step()


def test_an_rms_velocity_tolerance_stops_each_step_by_the_newton_decrement(small_grid):
    # The Newton decrement bounds the kinetic energy of the velocity error: each step ends once its mass-weighted RMS
    # is within the tolerance, which StepStats reports; a single-level smoother, which measures no decrement, stops
    # where its gradient bounds the same error.
    V, F = small_grid
    sim = hanging(V, F, solver="fmg", rel_grad=0.0, velocity_rms_tol=1e-3)
    for s in sim.step(3):
        assert s.status == "converged" and 0.0 < s.velocity_rms_error <= 1e-3
    smoother = hanging(V, F, solver="gs-chebyshev", rel_grad=0.0, velocity_rms_tol=1e-3, max_iters=5000)
    for s in smoother.step(2):
        assert s.status == "converged" and 0.0 < s.velocity_rms_error <= 1e-3


def test_the_accuracy_check_measures_each_step_against_its_minimizer(small_grid):
    # Off by default (NaN); on, a loose stop leaves a measurable distance to the step's minimizer, and a tight one
    # almost none.
    V, F = small_grid
    sim = hanging(V, F, solver="fmg", rel_grad=1e-8)
    assert not sim.check_accuracy
    assert all(math.isnan(s.true_velocity_error) for s in sim.step(1))
    sim.check_accuracy = True
    assert sim.check_accuracy
    tight = sim.step(2)
    loose_sim = hanging(V, F, solver="fmg", rel_grad=1e-1)
    loose_sim.check_accuracy = True
    loose = loose_sim.step(2)
    for t, l in zip(tight, loose):
        assert 0.0 <= t.true_velocity_error < 1e-4
        assert l.true_velocity_error > 10 * t.true_velocity_error
        assert 0.0 < l.true_velocity_rms <= l.true_velocity_error
