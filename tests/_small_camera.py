"""The small camera the slow end-to-end tests fly: a 640x480 image with half the focal length and one target
template. Small and quick, the same physics."""

SMALL_CAMERA = [
    "--set",
    "sim.width_px=640",
    "--set",
    "sim.height_px=480",
    "--set",
    "sim.focal_px=1000",
    "--set",
    "pipeline.targets=[t72]",
]
