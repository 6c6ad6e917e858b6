"""Wave phases at long sim_times that float32 cannot hold: the sea keeps moving at t ~ 1.2e8 s.

float32 represents 1.2e8 s only to 8 s (2^26.8 -> a step of 2^(26-23) = 8 s), so a phase computed from
a float32 time would freeze the sea for 8 s and then jump. The phases are reduced in float64 on the CPU
(SeaSurface.phase_offsets: omega t mod 2 pi) before the GPU sees them, and the host's queries use the
same float64 time. Checked at times float32 cannot represent, half a second apart: every wave's phase
advances by exactly omega dt (mod 2 pi), the frames differ, and the queried heights change."""
import math

import numpy as np

from helpers import tiny
from igserver.scene import apply_patch
from igserver.water import sea_surface

T0 = 1.2e8 + 0.37  # s: not a float32 value (float32(T0) = 1.2e8)


def test_phases_advance_by_omega_dt_at_times_float32_cannot_hold():
    assert float(np.float32(T0)) != T0 and float(np.float32(T0 + 0.5)) == float(np.float32(T0))
    scene = tiny({"ocean": {"enabled": True}, "weather": {"wind_speed": 9.0}})
    sea = sea_surface(scene.ocean, scene.weather)
    a, b = sea.phase_offsets(T0), sea.phase_offsets(T0 + 0.5)
    step = np.mod(a - b, 2 * math.pi)  # phase = ... - omega t: it falls by omega dt
    expected = np.mod(sea.waves.omega * 0.5, 2 * math.pi)
    err = np.abs(np.angle(np.exp(1j * (step - expected))))
    assert err.max() < 1e-6, err.max()


def test_heights_and_frames_move_at_long_times(renderer):
    scene = tiny({"ocean": {"enabled": True}, "weather": {"wind_speed": 9.0},
                  "camera": {"position": [0.0, 0.0, 4.0], "pitch": -20.0}})
    sea = sea_surface(scene.ocean, scene.weather)
    xy = np.array([[0.0, 10.0], [5.0, 20.0], [-7.0, 30.0]])
    h0 = sea.query(xy, T0)["height"]
    h1 = sea.query(xy, T0 + 0.5)["height"]
    assert np.abs(np.asarray(h1) - np.asarray(h0)).max() > 1e-3  # m: a 9 m/s sea moves in half a second
    f0 = renderer.render(apply_patch(scene, {"time": {"sim_time": T0}})).rgba.astype(int)
    f1 = renderer.render(apply_patch(scene, {"time": {"sim_time": T0 + 0.5}})).rgba.astype(int)
    assert np.abs(f1 - f0).mean() > 0.5  # the sea's picture changed: not frozen
