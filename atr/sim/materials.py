"""The materials table: what each `Mesh.material` index means and how it looks.

Textures are procedural and solid (a function of the world position of the surface point, never of
the view), so a surface looks the same from every viewpoint and a feature tracker sees the same
corners move with the geometry. Patterns are band-limited to the pixel footprint so that they do not
alias into flicker at long range. The texture code is in `_shading.py`; this module names the
indices.
"""

from __future__ import annotations

from dataclasses import dataclass

# Indices: int16 values stored in Mesh.material. Keep in step with the kernels in _shading.py.
GROUND = 0  # terrain: grass, asphalt, concrete or dirt chosen per point by the world's ground map
ASPHALT = 1
CONCRETE = 2
BRICK = 3
FACADE = 4  # plaster wall with a grid of windows
ROOF = 5  # flat roof: tar and gravel
ROOF_TILE = 6
GRASS = 7
FOLIAGE = 8
BARK = 9
CAMO = 10  # three-tone camouflage paint (green, brown, black) of the T-72
METAL = 11  # dark steel: gun, wheels, tracks
RUBBER = 12
GLASS = 13
OLIVE = 14  # olive drab paint of the confuser vehicles
CANVAS = 15
PAINT_RED = 16
PAINT_BLUE = 17
PAINT_WHITE = 18
PAINT_SILVER = 19
PAINT_BLACK = 20
DIRT = 21
DEFAULT = 22  # imported meshes: a neutral painted surface with grime
SAND = 23  # desert-sand camouflage variant (confusers)

CAR_PAINTS = (PAINT_RED, PAINT_BLUE, PAINT_WHITE, PAINT_SILVER, PAINT_BLACK)


@dataclass(frozen=True)
class Material:
    """One row of the materials table.

    Attributes:
        index: value stored in Mesh.material.
        name: short name.
        lidar_reflectivity: diffuse reflectance at the LIDAR wavelength (0..1), used for intensity.

    """

    index: int
    name: str
    lidar_reflectivity: float


MATERIALS: tuple[Material, ...] = (
    Material(GROUND, "ground", 0.3),
    Material(ASPHALT, "asphalt", 0.1),
    Material(CONCRETE, "concrete", 0.4),
    Material(BRICK, "brick", 0.3),
    Material(FACADE, "facade", 0.5),
    Material(ROOF, "roof", 0.15),
    Material(ROOF_TILE, "roof_tile", 0.3),
    Material(GRASS, "grass", 0.45),
    Material(FOLIAGE, "foliage", 0.5),
    Material(BARK, "bark", 0.2),
    Material(CAMO, "camouflage", 0.15),
    Material(METAL, "metal", 0.1),
    Material(RUBBER, "rubber", 0.05),
    Material(GLASS, "glass", 0.05),
    Material(OLIVE, "olive_drab", 0.15),
    Material(CANVAS, "canvas", 0.3),
    Material(PAINT_RED, "paint_red", 0.4),
    Material(PAINT_BLUE, "paint_blue", 0.3),
    Material(PAINT_WHITE, "paint_white", 0.7),
    Material(PAINT_SILVER, "paint_silver", 0.5),
    Material(PAINT_BLACK, "paint_black", 0.05),
    Material(DIRT, "dirt", 0.25),
    Material(DEFAULT, "default", 0.3),
    Material(SAND, "sand_paint", 0.4),
)

N_MATERIALS = len(MATERIALS)
MATERIAL_BY_NAME = {m.name: m.index for m in MATERIALS}
