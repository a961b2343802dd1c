#!/usr/bin/env python3
"""Writes the scripted sessions of retina_relocation and posterior_hyaloid (issue 38) from their geometry.

The needle and the vitrector move along the line from their trocar, so every waypoint is a distance along that line;
the light pipe's tip stays 5 mm back from the working tip on the line from the left trocar (its axis points at the
work). Prints the `scripts:` blocks; paste them into config/scenes/<scene>.yaml.
Usage: retina_scripts.py retina_relocation|posterior_hyaloid
"""
import math
import sys

R = 0.012  # eye radius (m)


def add(a, b): return [x + y for x, y in zip(a, b)]
def sub(a, b): return [x - y for x, y in zip(a, b)]
def mul(s, a): return [s * x for x in a]
def dot(a, b): return sum(x * y for x, y in zip(a, b))
def norm(a): return math.sqrt(dot(a, a))
def unit(a): return mul(1.0 / norm(a), a)


def trocar(angle_deg, azimuth_deg):
    a, z = math.radians(angle_deg), math.radians(azimuth_deg)
    return [R * math.sin(a) * math.cos(z), R * math.sin(a) * math.sin(z), R * math.cos(a)]


def pole_direction(offset_deg, azimuth_deg):
    """scene::posteriorPoleRotation(offset, azimuth) * (0, 0, -1)."""
    o, z = math.radians(offset_deg), math.radians(azimuth_deg)
    return [math.cos(z) * math.sin(o), math.sin(z) * math.sin(o), -math.cos(o)]


LEFT, RIGHT = trocar(45.0, 150.0), trocar(45.0, 30.0)


def light_for(tip):
    """The light pipe's tip 5 mm back from `tip` on the line from the left trocar."""
    return add(tip, mul(-0.005, unit(sub(tip, LEFT))))


def fmt(p): return "[%.6f, %.6f, %.6f]" % tuple(p)


def emit(name, comment, light, work, extra_keys):
    print("    # " + comment.replace("\n", "\n    # "))
    print("    %s:" % name)
    print("      - slot: left")
    print("        path:")
    for t, p in light:
        print("          - {t: %.2f, tip: %s}" % (t, fmt(p)))
    print("      - slot: right")
    print("        path:")
    for row in work:
        t, p = row[0], row[1]
        values = "".join(", %s: %s" % (k, ("%.3g" % v) if isinstance(v, float) else v)
                         for k, v in zip(extra_keys, row[2:]))
        print("          - {t: %.2f, tip: %s%s}" % (t, fmt(p), values))


def retina_relocation():
    height = 1.5e-4                      # the retina patch lies this far above the eye wall
    site = mul(R - height, pole_direction(4.0, 180.0))
    axis = unit(sub(site, RIGHT))
    radial = dot(axis, unit(site))       # how much of a step along the axis goes outwards

    def at(s): return add(site, mul(s, axis))  # s > 0: behind the retina surface, along the needle

    inside = 5e-5 / radial               # the tip 50 um behind the retina (the wall is 150 um behind it)
    # Expert: to 0.3 mm in front of the site, in at 0.4 mm/s, inject 0.75 ul/s for 3.2 s, wait, out along the axis.
    flow = 7.5e-10
    work = [(0.0, at(-0.015), 0.0), (1.5, at(-3e-4), 0.0), (2.4, at(inside), 0.0), (2.6, at(inside), 0.0),
            (2.7, at(inside), flow), (5.9, at(inside), flow), (6.0, at(inside), 0.0), (6.6, at(inside), 0.0),
            (7.4, at(-3e-4), 0.0), (8.6, at(-0.015), 0.0)]
    light = [(row[0], light_for(row[1])) for row in work]
    emit("expert", "Expert: approach to 0.3 mm in front of the site, pierce at 0.4 mm/s to 50 um under the retina, hold\n"
         "the needle still while injecting 0.75 ul/s for 3.2 s, wait 0.6 s, withdraw along the needle.", light, work,
         ["injection_flow"])
    # Novice: the syringe already running before the needle is in (fluid into the vitreous), pushed through to 120 um
    # (into the wall), full flow (1 ul/s), and the needle jerked 0.5 mm sideways while inside.
    side = unit([-axis[1], axis[0], 0.0])
    deep = 1.6e-4 / radial
    full = 1e-9
    work = [(0.0, at(-0.015), 0.0), (1.0, at(-3e-4), 0.0), (1.2, at(-3e-4), full), (1.6, at(deep), full),
            (2.6, at(deep), full), (2.8, add(at(inside), mul(5e-4, side)), full), (3.3, add(at(inside), mul(5e-4, side)), 0.0),
            (3.6, at(-3e-4), 0.0), (4.6, at(-0.015), 0.0)]
    light = [(row[0], light_for(row[1])) for row in work]
    emit("novice", "Novice: injects before the needle is in, pushes it into the wall, injects at full flow (1 ul/s)\n"
         "and jerks the needle 0.5 mm sideways while it is inside, then pulls it out.", light, work, ["injection_flow"])


def posterior_hyaloid():
    height = 2e-4                                   # the hyaloid lies this far above the retina
    def on_hyaloid(offset_deg, azimuth_deg, above):  # a point `above` m over the hyaloid
        return mul(R - height - above, pole_direction(offset_deg, azimuth_deg))
    # Expert: engage at the disc's temporal margin (12 deg from the pole towards the disc), the tip 0.1 mm over the
    # hyaloid; lift 1.2 mm at 0.4 mm/s, then carry the hyaloid towards the temporal periphery (to 14 deg the other
    # side) at 1 mm/s, 1.2 mm up; let go (suction off) and withdraw.
    engage = on_hyaloid(12.0, 0.0, 1e-4)
    lifted = on_hyaloid(12.0, 0.0, 1.3e-3)
    periphery = on_hyaloid(-14.0, 0.0, 1.3e-3)
    start = add(engage, mul(-0.006, unit(sub(engage, RIGHT))))
    work = [(0.0, start, 0.0), (1.5, on_hyaloid(12.0, 0.0, 6e-4), 0.0), (2.2, engage, 0.0), (2.4, engage, 0.5),
            (3.0, engage, 0.5), (6.0, lifted, 0.5), (11.5, periphery, 0.5), (12.0, periphery, 0.0),
            (13.5, start, 0.0)]
    light = [(row[0], light_for(row[1])) for row in work]
    emit("expert", "Expert: engage the hyaloid at the disc's temporal margin with suction 0.5 (cutter off);\n"
         "lift 1.2 mm at 0.4 mm/s so each adhesion peels, carry it 5 mm to the temporal\n"
         "periphery at 1 mm/s, let go, withdraw.", light, work, ["suction"])
    # Novice: full suction on the way down (the port aspirates the retina next to the disc), then a yank: 1.2 mm up in
    # 0.2 s, and the sweep at 4 mm/s.
    low = on_hyaloid(12.0, 0.0, -1.5e-4)
    work = [(0.0, start, 1.0), (1.2, on_hyaloid(12.0, 0.0, 6e-4), 1.0), (1.6, low, 1.0), (2.0, low, 1.0),
            (2.2, lifted, 1.0), (3.5, periphery, 1.0), (3.7, periphery, 0.0), (4.7, start, 0.0)]
    light = [(row[0], light_for(row[1])) for row in work]
    emit("novice", "Novice: full suction on the way down (the port reaches the retina beside the disc), then a yank\n"
         "(1.2 mm up in 0.2 s) and a fast sweep (4 mm/s) to the periphery.", light, work, ["suction"])


if __name__ == "__main__":
    {"retina_relocation": retina_relocation, "posterior_hyaloid": posterior_hyaloid}[sys.argv[1]]()
