#!/usr/bin/env python3
"""Writes the malformed inputs of the corpus (inputs/) from the shipped decks and mesh files.

Each input is one realistic mistake or hostile file; cases.toml says how each is run and
expected.txt (written by the test in bless mode) pins the exit code and first line of stderr.
Run from this directory: python3 make_inputs.py
"""
import os
import re

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
DECKS = os.path.join(ROOT, "decks")
OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "inputs")


def deck(name):
    with open(os.path.join(DECKS, name)) as f:
        return f.read()


BEAM = deck("slider_crank_beam.toml")
PLATE = deck("slider_crank_plate.toml")
RIGID = deck("slider_crank_rigid.toml")
RECT = deck("section_isotropic_rectangle.toml")
TUBE = deck("section_composite_tube.toml")
LAM = deck("laminate_paper_composite.toml")

PENDULUM = """title = "A rigid pendulum"

[rigid.bob]
mass = 1.0
inertia = [0.01, 0.01, 0.01]
position = [0.0, -0.5, 0.0]

[joint.pin]
kind = "spherical"
a = { body = "ground", point = [0.0, 0.0, 0.0] }
b = { body = "bob", point = [0.0, 0.0, 0.0] }

[force.gravity]
kind = "gravity"
acceleration = [0.0, -9.81, 0.0]

[response.bob_x]
kind = "position"
body = "bob"
component = "x"

[analysis]
t_end = 0.5
"""


def edit(text, old, new, count=1):
    assert old in text, (old, text[:200])
    return text.replace(old, new, count)


def write(name, text, binary=False):
    path = os.path.join(OUT, name)
    with open(path, "wb" if binary else "w") as f:
        f.write(text)


os.makedirs(OUT, exist_ok=True)

# --- TOML syntax, types, keys
write("syntax_unclosed_table.toml", edit(LAM, "[laminate.", "[laminate ", 1))
write("syntax_duplicate_key.toml", edit(RECT, 'material = "aluminium"', 'material = "aluminium"\nmaterial = "aluminium"'))
write("type_thickness_string.toml", re.sub(r"thickness = [0-9.e-]+", 'thickness = "thick"', LAM, count=1))
write("type_plies_numbers.toml", re.sub(r"plies = \[[^\]]*\]", "plies = [1, 2]", BEAM, count=1, flags=re.S))
write("type_elements_float.toml", edit(BEAM, "elements = 8 ", "elements = 8.5 "))
write("key_unknown_typo.toml", edit(RECT, "width = 0.04", "widht = 0.04"))
write("key_missing_E1.toml", edit(BEAM, "E1 = 128.0e9\n", ""))
write("key_missing_t_end.toml", edit(PENDULUM, "t_end = 0.5\n", "rtol = 1e-6\n"))
write("name_unknown_material.toml", edit(LAM, 'material = "paper_composite"', 'material = "paper_composit"'))
write("name_unknown_section.toml", edit(BEAM, 'section = "tube"', 'section = "pipe"'))
write("name_unknown_response_body.toml", edit(BEAM, 'kind = "mid-node-deflection"\nbody = "rod"', 'kind = "mid-node-deflection"\nbody = "shaft"'))
write("name_unknown_joint_kind.toml", edit(RIGID, 'kind = "translational"', 'kind = "prismatic"'))

# --- values
write("value_negative_thickness.toml", re.sub(r"thickness = [0-9.e-]+", "thickness = -0.001", LAM, count=1))
write("value_nan_angle.toml", re.sub(r"angle = [0-9.-]+", "angle = nan", LAM, count=1))
write("value_isotropic_E_negative.toml", edit(RECT, "E = 70.0e9", "E = -70.0e9"))
write("value_poisson_too_large.toml", edit(RECT, "nu = 0.33", "nu = 0.6"))
write("value_bad_rate_unit.toml", edit(RIGID, '"150 rad/s"', '"150 rad/min"'))
write("value_order_seven.toml", edit(PENDULUM, "t_end = 0.5\n", "t_end = 0.5\norder = 7\n"))
write("value_rtol_zero.toml", edit(PENDULUM, "t_end = 0.5\n", "t_end = 0.5\nrtol = 0.0\n"))
write("value_t_end_before_start.toml", edit(PENDULUM, "t_end = 0.5\n", "t_start = 1.0\nt_end = 0.5\n"))
write("value_huge_time_span.toml", edit(PENDULUM, "t_end = 0.5\n", "t_start = -1.7e308\nt_end = 1.7e308\n"))
write("value_tiny_output_step.toml", edit(PENDULUM, "t_end = 0.5\n", "t_end = 0.5\noutput_step = 1e-12\n"))
write("value_unknown_integrator.toml", edit(PENDULUM, "t_end = 0.5\n", 't_end = 0.5\nintegrator = "rk4"\n'))
write("value_unknown_error_weights.toml", edit(PENDULUM, "t_end = 0.5\n", 't_end = 0.5\nerror_weights = "metres"\n'))
write("value_negative_rigid_atol.toml", edit(PENDULUM, "mass = 1.0", "mass = 1.0\natol = -1e-9"))
write("value_baumgarte_negative.toml", edit(PENDULUM, "t_end = 0.5\n", "t_end = 0.5\nbaumgarte = { alpha = -5.0, beta = 5.0 }\n"))
write("value_correction_damping_negative.toml", edit(BEAM, 'correction_damping = "proportional"', "correction_damping = -0.1"))
write("value_correction_damping_word.toml", edit(BEAM, 'correction_damping = "proportional"', 'correction_damping = "critical"'))
write("value_zero_mass.toml", edit(PENDULUM, "mass = 1.0", "mass = 0.0"))
write("value_inertia_negative.toml", edit(PENDULUM, "inertia = [0.01, 0.01, 0.01]", "inertia = [0.01, -0.01, 0.01]"))
write("value_inertia_triangle.toml", edit(PENDULUM, "inertia = [0.01, 0.01, 0.01]", "inertia = [0.01, 0.01, 0.05]"))
write("value_marker_zero_axis.toml", edit(RIGID, 'axis = [1.0, 0.0, 0.0] }\nb = { body = "slider"', 'axis = [0.0, 0.0, 0.0] }\nb = { body = "slider"'))
write("value_marker_nan_point.toml", edit(PENDULUM, 'point = [0.0, 0.0, 0.0] }\nb', 'point = [nan, 0.0, 0.0] }\nb'))
write("value_design_unknown_laminate.toml", edit(BEAM, 'laminate = "tube_wall"\n\n[objective', 'laminate = "tube"\n\n[objective'))
write("value_design_unknown_kind.toml", edit(BEAM, '[design.theta]\n', '[design.theta]\nkind = "fibre-volume"\n'))
write("value_objective_unknown_response.toml", edit(BEAM, 'response = "mid_deflection"\nkind = "max"', 'response = "deflection"\nkind = "max"'))

# --- sizes (refused before allocation)
write("size_beam_1e9_elements.toml", edit(BEAM, "elements = 8 ", "elements = 1000000000 "))
write("size_shell_1e5_squared.toml", edit(PLATE, "elements = [64, 8]", "elements = [100000, 100000]"))
write("size_tube_1e9_around.toml", edit(BEAM, "elements_around = 32", "elements_around = 1000000000"))
write("size_section_rectangle_huge.toml", edit(RECT, "elements = [32, 6]", "elements = [100000, 100000]"))
write("size_modes_million.toml", edit(BEAM, "modes = 4\n", "modes = 1000000\n"))
write("size_fixed_step_1e-12.toml", edit(PENDULUM, "t_end = 0.5\n", 't_end = 0.5\nintegrator = "fixed"\nstep = 1e-12\n'))

# --- accepted before although wrong
write("wrong_empty.toml", "")
write("wrong_title_only.toml", 'title = "nothing here"\n')
write("wrong_objective_after_span.toml", BEAM + '\n[objective.late]\nresponse = "mid_deflection"\nkind = "at"\ntime = 1.0\n')
write("wrong_joint_ground_ground.toml", PENDULUM + '\n[joint.nothing]\nkind = "spherical"\na = { body = "ground", point = [0.0, 0.0, 0.0] }\nb = { body = "ground", point = [1.0, 0.0, 0.0] }\n')
write("wrong_fixed_and_driver.toml", edit(RIGID, "[joint.crank_drive]", '[joint.crank_weld]\nkind = "fixed"\na = { body = "ground", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0], reference = [1.0, 0.0, 0.0] }\nb = { body = "crank", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0], reference = [1.0, 0.0, 0.0] }\n\n[joint.crank_drive]') + "redundant = \"error\"\n")
write("wrong_fixed_and_driver_removed.toml", edit(RIGID, "[joint.crank_drive]", '[joint.crank_weld]\nkind = "fixed"\na = { body = "ground", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0], reference = [1.0, 0.0, 0.0] }\nb = { body = "crank", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0], reference = [1.0, 0.0, 0.0] }\n\n[joint.crank_drive]'))
write("wrong_tiny_beam.toml", edit(edit(BEAM, "end = [0.456, 0.0, 0.0]\norientation", "end = [0.152, 1e-150, 0.0]\norientation"), "[analysis]", "[analysis]"))
write("wrong_zero_length_spring.toml", PENDULUM + '\n[force.spring]\nkind = "spring-damper"\na = { body = "ground", point = [0.0, -0.5, 0.0] }\nb = { body = "bob", point = [0.0, -0.5, 0.0] }\nstiffness = 100.0\nfree_length = 0.0\n')
write("wrong_spring_negative.toml", PENDULUM + '\n[force.spring]\nkind = "spring-damper"\na = { body = "ground", point = [0.0, -0.5, 0.0] }\nb = { body = "bob", point = [0.0, -0.5, 0.0] }\nstiffness = -100.0\n')
ACTUATOR = '\n[force.motor]\nkind = "joint-torque"\na = { body = "ground", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }\nb = { body = "bob", point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }\n'
write("wrong_actuator_same_body.toml", PENDULUM + ACTUATOR.replace('body = "ground"', 'body = "bob"') + 'torque = 0.1\n')
write("wrong_actuator_two_laws.toml", PENDULUM + ACTUATOR + 'torque = 0.1\ncontrol = { kind = "pd", kp = 1.0, kd = 0.1, motion = { kind = "constant-speed", initial = 0.0, rate = 10.0 } }\n')
write("wrong_actuator_table_text.toml", PENDULUM + ACTUATOR + 'torque = { times = [0.0, 1.0], values = ["one", "two"] }\n')
write("wrong_actuator_no_motion.toml", PENDULUM + ACTUATOR + 'control = { kind = "pd", kp = 1.0, kd = 0.1 }\n')

# --- files that are not decks
write("binary_garbage.toml", bytes(range(256)) * 4, binary=True)

# --- section meshes
SIMPLE = open(os.path.join(ROOT, "fuzz", "seeds", "section_simple.txt")).read()
write("mesh_simple_ok.txt", SIMPLE)
write("mesh_simple_unknown_region.txt", edit(SIMPLE, "element quad8 core", "element quad8 kore"))
write("mesh_simple_nan_node.txt", edit(SIMPLE, "node 1 -0.01 -0.005", "node 1 nan -0.005"))
write("mesh_simple_missing_node.txt", edit(SIMPLE, "element quad8 core 1 2 3 4 5 6 7 8", "element quad8 core 1 2 3 4 5 6 7 99"))
write("mesh_simple_nan_angle.txt", edit(SIMPLE, "region skin cf 30", "region skin cf nan"))
write("mesh_simple_degenerate.txt", re.sub(r"node (\d+) \S+ \S+", r"node \1 0 0", SIMPLE))
GMSH = open(os.path.join(ROOT, "crates", "section", "tests", "data", "tube_q8.msh")).read()
lines = GMSH.split("\n")
i = lines.index("$Nodes")
write("mesh_gmsh_absurd_node_count.msh", "\n".join(lines[: i + 1] + ["1 100000000000000 1 100000000000000", "2 1 0 100000000000000000", "1", "$EndNodes", ""]))
write("mesh_gmsh_count_overflow.msh", "\n".join(lines[: i + 1] + ["18446744073709551615 1 1 1", "$EndNodes", ""]))
write("mesh_gmsh_truncated.msh", GMSH[: len(GMSH) // 2])
SHELL = open(os.path.join(ROOT, "fuzz", "seeds", "shell.msh")).read()
write("shell_ok.msh", SHELL)
write("shell_absurd_count.msh", edit(SHELL, "1 6 1 6\n2 1 0 6", "1 99999999999999 1 99999999999999\n2 1 0 99999999999999"))
write("shell_truncated.msh", SHELL[: len(SHELL) // 2])
write("shell_bad_node_ref.msh", edit(SHELL, "1 1 2 5\n", "1 1 2 50\n"))

SECTION_DECK = """[material.al]
E = 70e9
nu = 0.33
density = 2700

[section.s]
shape = "mesh"
file = "{file}"
format = "{format}"
"""
for f in ["mesh_simple_unknown_region.txt", "mesh_simple_nan_node.txt", "mesh_simple_missing_node.txt",
          "mesh_simple_nan_angle.txt", "mesh_simple_degenerate.txt", "missing_mesh.txt"]:
    write("section_" + f.replace(".txt", ".toml"), SECTION_DECK.format(file=f, format="simple"))
GMSH_DECK = """[material.al]
E = 70e9
nu = 0.33
density = 2700

[section.s]
shape = "mesh"
file = "{file}"
regions = {{ inner = {{ material = "al", angle = 0.0 }}, outer = {{ material = "al", angle = 0.0 }} }}
"""
for f in ["mesh_gmsh_absurd_node_count.msh", "mesh_gmsh_count_overflow.msh", "mesh_gmsh_truncated.msh"]:
    write("section_" + f.replace(".msh", ".toml"), GMSH_DECK.format(file=f))
SHELL_DECK = """[material.cf]
E1 = 140e9
E2 = 10e9
E3 = 10e9
G12 = 5e9
G13 = 5e9
G23 = 3.5e9
nu12 = 0.3
nu13 = 0.3
nu23 = 0.45
density = 1600

[laminate.plate]
plies = [{{ material = "cf", thickness = 1e-3, angle = 30.0 }}]

[body.plate]
kind = "shell"
laminate = "plate"
file = "{file}"
modes = 3
reference = "free-free"
"""
for f in ["shell_absurd_count.msh", "shell_truncated.msh", "shell_bad_node_ref.msh"]:
    write("body_" + f.replace(".msh", ".toml"), SHELL_DECK.format(file=f))
write("body_shell_ok.toml", SHELL_DECK.format(file="shell_ok.msh"))
write("pendulum.toml", PENDULUM)

# --- result files
write("not_hdf5.h5", "time,x\n0,1\n")
GOLD = open(os.path.join(ROOT, "crates", "cli", "tests", "golden", "slider_crank_rigid.h5"), "rb").read()
write("truncated.h5", GOLD[:4096], binary=True)
bad = bytearray(GOLD)
for k in range(200, 208):
    bad[k] = 0xFF
write("corrupt_header.h5", bytes(bad), binary=True)

# --- sections whose walls do not fit
I_BEAM = """[material.al]
E = 70.0e9
nu = 0.3
density = 2700.0

[laminate.flange]
plies = [{ material = "al", thickness = 0.004, angle = 0.0 }]

[laminate.web]
plies = [{ material = "al", thickness = 0.003, angle = 0.0 }]

[section.i]
shape = "i-beam"
width = 0.05
height = 0.008
walls = { top = "flange", bottom = "flange", web = "web" }
elements_per_ply = 2
"""
write("i_beam_no_web_height.toml", I_BEAM)

# --- tailored beams: segments of their own sections
ROD = '[body.rod]\nkind = "beam"\nsection = "tube"\n'
ROD_ELEMENTS = "elements = 8                # node 4 at mid-length carries the body frame (centre of mass)\n"


def segmented(segments, keep_section=False):
    text = BEAM if keep_section else edit(BEAM, ROD, '[body.rod]\nkind = "beam"\n')
    text = edit(text, ROD_ELEMENTS, "")
    return edit(text, 'orientation = [0.0, 1.0, 0.0]\n', 'orientation = [0.0, 1.0, 0.0]\nsegments = %s\n' % segments, 1)


HALVES = '[{ section = "tube", length = 0.152, elements = 4 }, { section = "tube", elements = 4 }]'
write("segments_with_section.toml", segmented(HALVES, keep_section=True))
write("segments_too_long.toml", segmented('[{ section = "tube", length = 0.2 }, { section = "tube", length = 0.2 }]'))
write("segments_too_short.toml", segmented('[{ section = "tube", length = 0.1 }, { section = "tube", length = 0.1 }]'))
write("segments_missing_length.toml", segmented('[{ section = "tube" }, { section = "tube", length = 0.1 }]'))
write("segments_unknown_section.toml", segmented('[{ section = "tub", length = 0.152 }, { section = "tube" }]'))
write("segments_empty.toml", segmented("[]"))
write("segments_zero_elements.toml", segmented('[{ section = "tube", length = 0.152, elements = 0 }, { section = "tube" }]'))
write("segments_unknown_key.toml", segmented('[{ section = "tube", lenght = 0.152 }, { section = "tube" }]'))
write("segments_nothing_left.toml", segmented('[{ section = "tube", length = 0.304 }, { section = "tube" }]'))

# --- tailored shells: regions of their own laminates
PATCH = edit(PLATE, "[body.rod]", '[laminate.patch]\nplies = [{ material = "paper_composite", thickness = 2.5e-3, angle = 45.0 }]\n\n[body.rod]')


def regioned(regions):
    return edit(PATCH, '\nreference = "supports"\n', '\nregions = %s\nreference = "supports"\n' % regions)


write("regions_empty_box.toml", regioned('[{ laminate = "patch", box = [[1.0, 1.0, 1.0], [2.0, 2.0, 2.0]] }]'))
write("regions_no_whole_element.toml", regioned('[{ laminate = "patch", plane = { x = 0.0 } }]'))
write("regions_element_out_of_range.toml", regioned('[{ laminate = "patch", elements = [0, 1, 5000] }]'))
write("regions_two_ways.toml", regioned('[{ laminate = "patch", elements = [0], box = [[0.0, 0.0, -1.0], [0.1, 0.04, 1.0]] }]'))
write("regions_unknown_laminate.toml", regioned('[{ laminate = "pach", elements = [0] }]'))
write("regions_element_twice.toml", regioned('[{ laminate = "patch", elements = [3, 3] }]'))
write("regions_on_a_beam.toml", edit(BEAM, 'section = "tube"\nstart', 'section = "tube"\nregions = [{ laminate = "tube_wall", elements = [0] }]\nstart'))
write("segments_on_a_shell.toml", regioned('[{ laminate = "patch", elements = [0] }]').replace('regions = [{ laminate = "patch", elements = [0] }]', 'segments = [{ section = "tube" }]'))

# --- operating points (flexsens static)
ROTOR = deck("rotor_blade_composite.toml")
SPEEDS = 'speeds = ["0 rpm", "125 rpm", "250 rpm", "375 rpm", "500 rpm", "625 rpm", "750 rpm"]'
write("operating_unknown_driver.toml", edit(ROTOR, 'driver = "motor"', 'driver = "motr"'))
write("operating_driver_not_angle.toml", edit(ROTOR, 'driver = "motor"', 'driver = "hub"'))
write("operating_speeds_decreasing.toml", edit(ROTOR, SPEEDS, 'speeds = ["750 rpm", "0 rpm"]'))
write("operating_speed_without_driver.toml", edit(ROTOR, 'driver = "motor"\n', ''))
write("operating_speed_bad_unit.toml", edit(ROTOR, SPEEDS, 'speeds = ["750 rpmm"]'))
write("operating_zero_modes.toml", edit(ROTOR, "modes = 8\norders", "modes = 0\norders"))
write("operating_unknown_key.toml", edit(ROTOR, "modes = 8\norders", "mode = 8\norders"))
write("operating_not_steady.toml", edit(BEAM, "[analysis]", '[operating]\ndriver = "crank_drive"\nspeeds = ["100 rpm"]\n\n[analysis]'))
write("operating_margin_at_rest.toml", edit(ROTOR, 'section = "strip"\n\n[operating]', 'section = "strip"\nlower = 0.0\nupper = 45.0\n\n[operating]') + '\n[optimize]\nminimize = "order_margin.1.1.2"\n')
