"""Simulated world and sensors: urban scenes with a T-72, UAV orbits, camera, IMU and LIDAR (Table
II).

Public API:
    Mesh, load/save in atr.io.mesh; VEHICLES (t72, ifv, truck_6x6, car); Scenario, scenario();
    SimConfig; build_world(); simulate_flight() -> Iterator[SensorFrame]; Renderer.
"""

from atr.sim.config import SimConfig
from atr.sim.flight import SensorFrame, TargetTruth, imu_samples, simulate_flight
from atr.sim.mesh import Mesh
from atr.sim.scenarios import Scenario, all_scenarios, custom_scenario, scenario
from atr.sim.vehicles import VEHICLES, car, ifv, t72, truck_6x6
from atr.sim.world import World, build_world

__all__ = [
    "VEHICLES",
    "Mesh",
    "Scenario",
    "SensorFrame",
    "SimConfig",
    "TargetTruth",
    "World",
    "all_scenarios",
    "build_world",
    "car",
    "custom_scenario",
    "ifv",
    "imu_samples",
    "scenario",
    "simulate_flight",
    "t72",
    "truck_6x6",
]
