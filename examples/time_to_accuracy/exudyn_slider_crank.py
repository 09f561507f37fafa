"""The steel slider-crank of steel_slider_crank.toml in Exudyn (https://github.com/jgerstmayr/EXUDYN),
for the time-to-accuracy comparison of compare.py: the rod as 2-D ANCF cable elements
(geometrically exact Euler-Bernoulli, with axial strain), the crank a rigid body turned at a
constant 150 rad/s by a velocity-level coordinate constraint, the slider a point mass on the
rod's last node held on the x-axis; Exudyn's generalised-alpha integrator at a fixed step.

    python3 exudyn_slider_crank.py --elements 8 --step 2e-4 --out exudyn.csv

writes t, mid_deflection (the mid-length node's distance from the chord of the rod's ends, over
the rod's length, positive on the left of crank pin -> slider) and slider_x (m) every 0.1 ms, and
prints the solver's CPU seconds (model assembly and time integration, not the imports) as JSON.
"""
import argparse
import json
import time

import exudyn as exu
import exudyn.itemInterface as ei
import numpy as np

CRANK = 0.152
ROD = 0.304
DIAMETER = 6e-3
E = 2.0e11
DENSITY = 7850.0
SLIDER = 0.038
OMEGA = 150.0
T_END = 0.1
OUTPUT = 1e-4


def build(mbs, elements):
    area = np.pi * DIAMETER**2 / 4
    second_moment = np.pi * DIAMETER**4 / 64
    ground = mbs.AddObject(ei.ObjectGround())
    ground_node = mbs.AddNode(ei.NodePointGround())
    # the crank about the origin: angle 0, turning at OMEGA
    crank_node = mbs.AddNode(ei.NodeRigidBody2D(referenceCoordinates=[0, 0, 0],
                                                initialVelocities=[0, 0, OMEGA]))
    crank = mbs.AddObject(ei.ObjectRigidBody2D(mass=0.038, inertia=7.32e-5,
                                               nodeNumber=crank_node))
    pivot_ground = mbs.AddMarker(ei.MarkerBodyPosition(bodyNumber=ground))
    pivot_crank = mbs.AddMarker(ei.MarkerBodyPosition(bodyNumber=crank))
    mbs.AddObject(ei.ObjectJointRevolute2D(markerNumbers=[pivot_ground, pivot_crank]))
    ground_coordinate = mbs.AddMarker(ei.MarkerNodeCoordinate(nodeNumber=ground_node, coordinate=0))
    crank_angle = mbs.AddMarker(ei.MarkerNodeCoordinate(nodeNumber=crank_node, coordinate=2))
    mbs.AddObject(ei.ObjectConnectorCoordinate(markerNumbers=[ground_coordinate, crank_angle],
                                               velocityLevel=True, offset=OMEGA))
    # the rod, straight along x, with the rigid mechanism's velocities at crank angle 0: the
    # crank pin at OMEGA CRANK along y, the rod turning about the slider (at rest)
    pin_speed = OMEGA * CRANK
    rod_rate = -pin_speed / ROD
    nodes = []
    for k in range(elements + 1):
        s = ROD * k / elements
        nodes.append(mbs.AddNode(ei.NodePoint2DSlope1(
            referenceCoordinates=[CRANK + s, 0, 1, 0],
            initialVelocities=[0, pin_speed * (1 - s / ROD), 0, rod_rate])))
    for k in range(elements):
        mbs.AddObject(ei.ObjectANCFCable2D(
            length=ROD / elements, massPerLength=DENSITY * area,
            bendingStiffness=E * second_moment, axialStiffness=E * area,
            nodeNumbers=[nodes[k], nodes[k + 1]]))
    crank_pin = mbs.AddMarker(ei.MarkerBodyPosition(bodyNumber=crank, localPosition=[CRANK, 0, 0]))
    rod_start = mbs.AddMarker(ei.MarkerNodePosition(nodeNumber=nodes[0]))
    mbs.AddObject(ei.ObjectJointRevolute2D(markerNumbers=[crank_pin, rod_start]))
    # the slider: a point mass on the rod's last node, held on the x-axis
    mbs.AddObject(ei.ObjectMassPoint2D(mass=SLIDER, nodeNumber=nodes[-1]))
    slider_y = mbs.AddMarker(ei.MarkerNodeCoordinate(nodeNumber=nodes[-1], coordinate=1))
    mbs.AddObject(ei.ObjectConnectorCoordinate(markerNumbers=[ground_coordinate, slider_y]))
    return [mbs.AddSensor(ei.SensorNode(nodeNumber=nodes[k], storeInternal=True,
                                        writeToFile=False,
                                        outputVariableType=exu.OutputVariableType.Position))
            for k in (0, elements // 2, elements)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--elements", type=int, default=8)
    parser.add_argument("--step", type=float, default=2e-4)
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    if args.elements % 2:
        parser.error("--elements must be even (the mid-length point a node)")
    steps = round(T_END / args.step)
    if abs(steps * args.step - T_END) > 1e-9 * T_END:
        parser.error("--step must divide 0.1 s")

    start = time.process_time()
    sc = exu.SystemContainer()
    mbs = sc.AddSystem()
    sensors = build(mbs, args.elements)
    mbs.Assemble()
    settings = exu.SimulationSettings()
    settings.timeIntegration.numberOfSteps = steps
    settings.timeIntegration.endTime = T_END
    settings.timeIntegration.verboseMode = 0
    settings.timeIntegration.generalizedAlpha.spectralRadius = 0.9
    settings.solution.file.write = False
    settings.solution.sensors.writePeriod = max(OUTPUT, args.step)
    settings.show.statistics = False
    settings.show.computationTime = False
    mbs.SolveDynamic(settings)
    solver = time.process_time() - start

    a, m, b = (mbs.GetSensorStoredData(s) for s in sensors)
    with open(args.out, "w") as out:
        out.write("t,mid_deflection,slider_x\n")
        for ra, rm, rb in zip(a, m, b):
            chord = (rb[1:3] - ra[1:3]) / np.linalg.norm(rb[1:3] - ra[1:3])
            rel = rm[1:3] - ra[1:3]
            w = chord[0] * rel[1] - chord[1] * rel[0]
            out.write(f"{ra[0]:.6e},{w / ROD:.12e},{rb[1]:.12e}\n")
    print(json.dumps({"solver_cpu": solver, "steps": steps}))


if __name__ == "__main__":
    main()
