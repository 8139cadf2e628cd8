"""The fabric presets: each fabric's measured values as its source gives them, and their conversion to the
SI values of a material (warp_cloth/materials.py), so that every number of a preset can be traced back.

Wang, O'Brien and Ramamoorthi measured ten fabrics ("Data-driven elastic models for cloth: modeling and
measurement", ACM Transactions on Graphics 30(4), SIGGRAPH 2011) and published them in the material files
of their simulator ARCSim (materials/*.json, with its README naming each fabric and its use), in SI units:
``density`` (kg/m^2); ``stretching``, six samples of four stiffnesses (N/m) of the energy per unit area
1/2 k0 e00^2 + k1 e00 e11 + 1/2 k2 e11^2 + k3 e01^2 in Green's strain e, of which the first sample is the
stiffness at zero strain (the others, at 1/6 strain in five directions, are not used here); ``bending``,
three rows (hinges along u, along the bias, along v) of five samples (curvature 0 to 40 1/m) of the
stiffness k of the hinge energy k l^2 / (2 a) (theta - theta0)^2 / 4 (l: the hinge's length, a: its two
faces' area). ARCSim doubles each stretching sample when it reads it (dde.cpp); ``wang2011`` repeats that.
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass

WANG_2011 = ("Wang, O'Brien & Ramamoorthi 2011, Data-driven elastic models for cloth, ACM TOG 30(4); "
             "measured data as published in ARCSim's materials/{file}")


@dataclass(frozen=True)
class PublishedDrape:
    """Cusick drape coefficients measured on fabrics of a preset's class: the range (fractions) and where."""

    range: tuple[float, float]
    source: str


@dataclass(frozen=True)
class FabricData:
    """One preset's values in SI units (see ``materials.Material`` for their meaning) and where they come from."""

    fabric: str
    source: str
    density: float
    stretch: tuple[float, float]
    shear: float
    bending: tuple[float, float]
    drape: PublishedDrape | None = None  # its class's measured drape coefficients (warp-cloth drape-test)


def wang2011(fabric: str, file: str, density: float, stretching: tuple[float, float, float, float],
             bending: tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]) -> FabricData:
    """A preset from an ARCSim material file: its density, the first row of ``stretching`` and the three rows
    of ``bending``, as the file gives them.

    Stretch: ARCSim's stiffnesses are twice the file's (k = 2 x sample); a strip pulled along u and free to
    narrow carries k0 - k1^2 / k2 per unit width and strain (likewise k2 - k1^2 / k0 along v). Shear: the
    energy k3 e01^2 with the shear angle gamma = 2 e01 is 1/2 (k3 / 2) gamma^2, so G = k3 / 2, the file's
    sample. Bending: bent along u to curvature kappa, a mesh of right triangles has one hinge along v per
    cell, of angle kappa h and energy k kappa^2 h^2 / 8: per area k kappa^2 / 8 = 1/2 B kappa^2, so B = k / 4;
    a curvature along u bends about hinges along v, the file's third row (the first is along v). Of the
    five curvature samples, the median is taken."""
    k0, k1, k2, k3 = (2.0 * s for s in stretching)
    along_v, _, along_u = (statistics.median(row) / 4.0 for row in bending)
    return FabricData(fabric, WANG_2011.format(file=file), density, (k0 - k1 * k1 / k2, k2 - k1 * k1 / k0), k3 / 2.0,
                      (along_u, along_v))


PRESETS: dict[str, FabricData] = {
    "cotton": wang2011(
        "cotton-rich twill for trousers (65% cotton, 35% polyester; 'royal-target')", "royal-target.json",
        0.220, (2016.55456, 9.170511, 2034.97644, 104.759674),
        ((125.409805e-6, 167.284561e-6, 215.412750e-6, 215.090790e-6, 223.861038e-6),
         (107.997696e-6, 120.583267e-6, 144.141678e-6, 140.606689e-6, 153.048309e-6),
         (125.409805e-6, 167.284561e-6, 215.412750e-6, 215.090790e-6, 227.861038e-6))),
    "denim": wang2011(
        "11 oz denim for jeans (99% cotton, 1% spandex; '11oz-black-denim')", "11oz-black-denim.json",
        0.324, (205.352005, 10.234077, 1013.88629, 53.387184),
        ((64.196457e-6, 60.286175e-6, 60.943428e-6, 62.433697e-6, 19.824701e-6),
         (73.384567e-6, 59.671982e-6, 61.080757e-6, 68.242569e-6, 36.033474e-6),
         (96.951576e-6, 107.848228e-6, 113.060738e-6, 120.569740e-6, 79.781021e-6))),
    "polyester": wang2011(
        "woven polyester for jackets (100% polyester; 'tango-red-jet-set')", "tango-red-jet-set.json",
        0.113, (43.067627, 54.373299, 171.424835, 14.314700),
        ((14.293814e-6, 8.949391e-6, 30.011126e-6, 36.081490e-6, 18.363136e-6),
         (21.951700e-6, 22.446325e-6, 18.408735e-6, 19.598495e-6, 12.071854e-6),
         (20.345654e-6, 22.696880e-6, 15.698071e-6, 13.466827e-6, 7.556618e-6))),
    "jersey": wang2011(
        "interlock knit for T-shirts (60% cotton, 40% polyester; 'gray-interlock')", "gray-interlock.json",
        0.187, (16.593832, -14.695990, 34.477123, 36.860302),
        ((23.191698e-6, 32.932217e-6, 34.406498e-6, 39.014420e-6, 23.382786e-6),
         (24.749964e-6, 18.651314e-6, 16.370552e-6, 25.095791e-6, 8.860165e-6),
         (14.267624e-6, 7.052906e-6, 14.515154e-6, 24.665127e-6, 19.383726e-6))),
}
