#!/usr/bin/env python3
"""Derive each preset's speed PI and contact damping (docs/physics.md, "How each preset is derived").

Speed PI: symmetric optimum on the drive's small time constants T_sum (torque demand held for
half a speed cycle, speed from a backward difference: half a cycle, the speed filter, the
current loop as a first-order lag): k_sp = J_m / (2 T_sum), T_si = 4 T_sum. J_m, because the
loop's bandwidth (~230 Hz) lies above the two-mass resonance (60-95 Hz): there the motor sees
its own inertia.

Contact damping: the coefficient of restitution e = 0.41 (the paper's eq. 10 with f = 0.6 k_v)
of the load striking the drive, which now yields: the motor (J_m / r^2 at the load) is held by
the speed loop, a damper of k_sp / r^2 (the PI's integral and the loop's delays neglected over
an impact of ~5 ms). The contact is the emulator's: spring and damper, the force clipped so it
never pulls; `damping_ratio` is relative to the two-mass reduced mass. Bisection on it.

Pure python, no dependencies: python3 docs/derive-speed-loop.py
"""
import math

SPEED_CYCLE_S = 125e-6      # [DOMAIN] every preset
SPEED_FILTER_S = 0.25e-3    # [est] every preset
CURRENT_LOOP_HZ = 500.0     # [paper] 500-1000 Hz
RESTITUTION = 0.41          # [paper] eq. 10 with f = 0.6 k_v (eq. 13)

T_SUM = SPEED_CYCLE_S / 2 + SPEED_CYCLE_S / 2 + SPEED_FILTER_S + 1 / (2 * math.pi * CURRENT_LOOP_HZ)

# name: (J_m [kg m^2], r [m/rad or rad/rad: load motion per motor radian], load mass [kg] or
# inertia [kg m^2], contact stiffness [N/m or N m/rad]), from physics/presets/*.toml
PRESETS = {
    "cnc1": (0.0048, 0.010 / (2 * math.pi), 800.0, 200e6),
    "cnc2": (0.0092, 0.016 / (2 * math.pi), 600.0, 150e6),
    "cnc3": (0.012, 1 / 1258.5, 8000.0, 9700 * 206264.806),
    "cnc4": (0.0169, 0.160 / 2 / 60, 4000.0, 400e6),  # pinion 160 mm, gear 60
    "cnc5": (0.0069, 1 / 720, 1500.0, 1820 * 206264.806),
}


def restitution(m, big_m, k, zeta_key, damper, dt=2e-7):
    """Load m at 1 m/s strikes the motor mass big_m (at rest, held by `damper`)."""
    m_red = m * big_m / (m + big_m)
    c = 2 * zeta_key * math.sqrt(k * m_red)
    x = y = 0.0
    vx, vy = 1.0, 0.0
    t = 0.0
    while True:
        d, dd = x - y, vx - vy
        f = k * d + c * dd
        if t > 0 and (d <= 0 or f <= 0):
            return -(vx - vy)
        f = max(f, 0.0)
        vx -= f / m * dt
        vy += (f - damper * vy) / big_m * dt
        x += vx * dt
        y += vy * dt
        t += dt


def main():
    print(f"T_sum = {T_SUM * 1e3:.3f} ms, T_si = 4 T_sum = {4 * T_SUM * 1e3:.2f} ms")
    for name, (jm, r, m, k) in PRESETS.items():
        kp = jm / (2 * T_SUM)
        big_m = jm / r**2
        lo, hi = 0.05, 0.8
        for _ in range(40):
            z = (lo + hi) / 2
            if restitution(m, big_m, k, z, kp / r**2) > RESTITUTION:
                lo = z
            else:
                hi = z
        m_red = m * big_m / (m + big_m)
        f_res = math.sqrt(k / m_red) / (2 * math.pi)
        print(f"{name}: speed_kp_nms_per_rad = {kp:.3f}, damping_ratio = {z:.3f} "
              f"(J_m r^2 / m = {big_m / m:.2f}, two-mass resonance {f_res:.0f} Hz)")


if __name__ == "__main__":
    main()
