"""Unit tests for the monoped's hop metrics (hopper_training/hop_metrics.py) on hand-made step sequences, and
their way through the env's info into the task's metrics."""
import dataclasses

import pytest
from test_monoped import readings

from hopper_training.envs.base import monoped_metrics
from hopper_training.envs.stay_up import STAY_UP, MonopedEnv
from hopper_training.hop_metrics import MIN_FLIGHT_S, HopTracker, fit_flight
from robot_rl import Episode

from fake_backend import FakeBackend

DT = 0.02
G = 9.81


def track(samples, start=(0.0, 0.0, 0.88), contact_at_start=True):
    """A tracker fed (contact, x, y, z) samples DT apart after a start sample."""
    tracker = HopTracker(DT)
    tracker.reset(0.0, start, contact_at_start)
    for k, (contact, x, y, z) in enumerate(samples, start=1):
        tracker.add(k * DT, (x, y, z), contact)
    return tracker


def ballistic(steps, top_rise, z0=0.88):
    """Flight samples (no contact) of an arc that rises `top_rise` above z0 and comes back in `steps` samples."""
    duration = (steps + 1) * DT
    v = G * duration / 2
    arc = [(False, 0.0, 0.0, z0 + v * t - G * t * t / 2) for t in (DT * k for k in range(1, steps + 1))]
    assert v * v / (2 * G) == pytest.approx(top_rise, rel=0.3)
    return arc


def test_apex_of_a_noise_free_arc_is_its_top_not_the_highest_sample():
    times = [0.02 * k for k in range(10)]
    heights = [1.0 + 1.0 * t - G * t * t / 2 for t in times]
    assert fit_flight(times, heights) == pytest.approx((1.0 + 1.0 / (2 * G), 1.0))
    rising = [(t, 1.0 + 3.0 * t - G * t * t / 2) for t in times[:3]]  # the top is after the samples
    assert fit_flight(*zip(*rising))[0] == pytest.approx(rising[-1][1])


def test_flights_count_as_hops_only_from_contact_to_contact_and_long_enough():
    stance = [(True, 0.0, 0.0, 0.88)] * 3
    long_flight = ballistic(10, 0.05)
    short_flight = ballistic(round(MIN_FLIGHT_S / DT) - 1, 0.005)
    tracker = track(stance + long_flight + stance + short_flight + stance + long_flight + stance + long_flight)
    assert tracker.hops == 2  # the short flight is a bounce; the last flight has not landed
    rise = (11 * DT) ** 2 * G / 8  # v^2 / 2g with v = g T / 2, T = 11 steps from lift-off to landing
    assert tracker.apex_height == pytest.approx(rise, abs=1e-9)


def test_a_foot_off_the_ground_while_the_base_falls_is_no_hop():
    stance = [(True, 0.0, 0.0, 0.88)] * 3
    falling = [(False, 0.0, 0.0, 0.88 - 0.5 * G * (k * DT) ** 2) for k in range(1, 6)]
    assert track(stance + falling + stance).hops == 0


def test_a_flight_from_the_start_in_the_air_is_no_hop():
    tracker = track(ballistic(10, 0.05) + [(True, 0.0, 0.0, 0.88)], contact_at_start=False)
    assert (tracker.hops, tracker.apex_height) == (0, 0.0)


def test_forward_speed_is_over_the_last_five_seconds_and_drift_is_lateral():
    # 3 s standing, then 6 s at 0.4 m/s along +x, drifting along y: 9 s at 20 ms.
    samples, x = [], 0.0
    for k in range(1, 451):
        x += 0.4 * DT if k > 150 else 0.0
        samples.append((True, x, -0.001 * k, 0.88))
    tracker = track(samples, start=(0.0, 0.05, 0.88))
    assert tracker.forward_speed == pytest.approx(0.4)
    assert tracker.lateral_drift == pytest.approx(0.05 + 0.45)
    short = track(samples[:100], start=(0.0, 0.05, 0.88))  # 2 s standing: over the whole episode
    assert short.forward_speed == 0.0


def test_the_env_puts_the_figures_in_info_and_the_metrics_read_them():
    def on_ground(k, x=0.0):
        return readings(position=(x, 0.0, 0.88), total_force=(0.0, 0.0, 7.0), stamp=k * DT)
    heights = [0.9, 0.91, 0.91, 0.9]
    air = [readings(position=(0.0, 0.0, z), stamp=k * DT) for k, z in enumerate(heights, start=2)]
    backend = FakeBackend(on_ground(0), script=[on_ground(1), *air, on_ground(6, x=0.1)])
    env = MonopedEnv(backend=backend, params=dataclasses.replace(STAY_UP.default_params(), action_mode="tutorial"))
    env.reset()
    for _ in range(6):
        *_, info = env.step(0)
    assert info["hops"] == 1
    assert info["apex_height"] == pytest.approx(fit_flight([k * DT for k in range(2, 6)], heights)[0] - 0.88)
    metrics = monoped_metrics(Episode(steps=6, return_=0.0, terminated=False, duration=0.12, info=info))
    assert metrics["hops"] == 1.0 and metrics["fell"] is False and metrics["upright_whole_horizon"] is True
    assert metrics["apex_height"] == info["apex_height"] and metrics["lateral_drift"] == 0.0
    assert metrics["forward_speed"] == pytest.approx(0.1 / 0.12)
