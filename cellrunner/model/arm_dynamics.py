"""The arms' masses, link inertias and joint torques: what a joint can accelerate.

A UR joint's motor gives at most its rated torque (``JOINT_TORQUE_MAX_NM``, Universal
Robots' manuals and ur_description's ``max_effort``). A plan that asks a joint for more
torque than that is not followed: on a UR10e stretched out, the shoulder (330 N m) moving
14.9 kg m^2 of arm reaches about 22 rad/s^2, not the 40 rad/s^2 the controller accepts
as a command, and the arm overshoots a line's end by 15-19 mm (docs/check-truth.md, "A
joint gives only its torque"). So :mod:`cellrunner.planning.timing` times every motion
under these torques as well as the joint acceleration limits, with the twin's very
masses and inertias: ``LINK_INERTIA`` is each link's mass, centre and inertia tensor in
its joint's frame (the DH frame the joint turns in), as the twin computes them from the
arm's collision meshes at a uniform density making up ``ARM_MASS_KG``
(``tests/planning/test_arm_dynamics.py`` compares them with the compiled twin), and
``armature_kgm2`` the harmonic drives' reflected rotor inertia, which the twin's joints
carry too. Arms without collision meshes have no twin and no entry: only the joint
limits time their motions.
"""

from __future__ import annotations

from typing import NamedTuple

from cellrunner.model.robots import RobotSpec

# Arm masses (kg), datasheets / UR manuals.
ARM_MASS_KG = {
    "ur3": 11.0,
    "ur5": 18.4,
    "ur10": 28.9,
    "ur3e": 11.2,
    "ur5e": 20.6,
    "ur10e": 33.5,
    "ur16e": 33.1,
    "ur7e": 20.6,  # the UR5e renamed
    "ur12e": 33.5,  # the UR10e renamed
    "ur15": 40.2,  # sums of ur_description's link masses (UR15, UR18); UR8 Long assumed
    "ur18": 39.5,
    "ur8long": 42.0,
    "ur20": 64.0,  # datasheets
    "ur30": 63.5,
}
# Joint torque limits (N m, base..wrist 3), datasheets / UR manuals.
_TORQUE_SMALL = (56.0, 56.0, 28.0, 12.0, 12.0, 12.0)
_TORQUE_MEDIUM = (150.0, 150.0, 150.0, 28.0, 28.0, 28.0)
_TORQUE_LARGE = (330.0, 330.0, 150.0, 56.0, 56.0, 56.0)
_TORQUE_UR18 = (433.0, 433.0, 204.0, 70.0, 70.0, 70.0)  # ur_description max_effort
_TORQUE_UR20 = (738.0, 738.0, 433.0, 107.0, 107.0, 107.0)  # ur_description max_effort
JOINT_TORQUE_MAX_NM = {
    "ur3": _TORQUE_SMALL,
    "ur3e": _TORQUE_SMALL,
    "ur5": _TORQUE_MEDIUM,
    "ur5e": _TORQUE_MEDIUM,
    "ur10": _TORQUE_LARGE,
    "ur10e": _TORQUE_LARGE,
    "ur16e": _TORQUE_LARGE,
    "ur7e": _TORQUE_MEDIUM,
    "ur12e": _TORQUE_LARGE,
    "ur15": _TORQUE_UR18,  # assumed: the UR18's joint sizes (same DH d1, d4-d6)
    "ur18": _TORQUE_UR18,
    "ur8long": _TORQUE_UR18,  # assumed, as the UR15
    "ur20": _TORQUE_UR20,
    "ur30": _TORQUE_UR20,
}
# Reflected rotor inertia of the harmonic drives (kg m^2) of a UR5, scaled by arm size.
_ARMATURE_UR5 = (0.6, 0.6, 0.3, 0.06, 0.06, 0.06)


def armature_kgm2(spec: RobotSpec) -> tuple[float, ...]:
    """The reflected rotor inertia of each joint (kg m^2): a UR5's, scaled by the square
    of the arm's reach."""
    scale = (spec.reach_m / 0.85) ** 2
    return tuple(a * scale for a in _ARMATURE_UR5)


def joint_torque_max_nm(spec: RobotSpec) -> tuple[float, ...]:
    """Each joint's rated torque (N m)."""
    return JOINT_TORQUE_MAX_NM.get(spec.name, _TORQUE_MEDIUM)


class LinkInertia(NamedTuple):
    """One link's mass (kg), centre of mass (m) and inertia tensor about that centre
    (kg m^2: xx, yy, zz, xy, xz, yz), in the frame of the joint that turns it."""

    mass_kg: float
    com_m: tuple[float, float, float]
    inertia_kgm2: tuple[float, float, float, float, float, float]


def link_inertias(spec: RobotSpec) -> tuple[LinkInertia, ...] | None:
    """The six links' inertias of ``spec``'s arm (its renamed twins share them), or None
    for an arm with no collision meshes (and so no twin)."""
    return LINK_INERTIA.get(spec.arm)


# generated from the twin's compiled model (see the module docstring)
LINK_INERTIA: dict[str, tuple[LinkInertia, ...]] = {
    "ur3": (
        LinkInertia(
            2.23514,
            (8.78724e-07, -0.00820706, 0.149448),
            (0.00348491, 0.00333534, 0.00256342, -1.88477e-06, -1.41258e-06, 0.000122686),
        ),
        LinkInertia(
            4.9023,
            (-0.114135, 8.96483e-05, 0.118926),
            (0.00579376, 0.0566282, 0.0550641, 1.61254e-05, 0.000691273, 2.29543e-05),
        ),
        LinkInertia(
            2.05796,
            (-0.113261, 1.09039e-05, 0.0321423),
            (0.00144022, 0.0151368, 0.0147612, 2.17893e-06, -0.00116583, 5.51196e-07),
        ),
        LinkInertia(
            0.717473,
            (-2.38209e-05, 0.000144312, 0.102131),
            (0.00067594, 0.000483081, 0.000577533, -6.98351e-07, 1.27555e-09, -2.54165e-06),
        ),
        LinkInertia(
            0.725842,
            (1.49328e-05, -0.00194599, 0.0748285),
            (0.00068187, 0.000486176, 0.000583572, -3.69086e-08, -4.91831e-08, 6.92919e-07),
        ),
        LinkInertia(
            0.361282,
            (-4.84022e-05, 0.00161312, 0.0588559),
            (0.000123858, 0.000133286, 0.000168949, -2.61112e-07, -5.17013e-10, -3.89602e-06),
        ),
    ),
    "ur5": (
        LinkInertia(
            3.25995,
            (6.01601e-05, -0.00886057, 0.0863407),
            (0.00670268, 0.00646475, 0.00625007, -4.6931e-05, 3.23839e-05, 0.000232671),
        ),
        LinkInertia(
            9.76526,
            (-0.211875, -6.18382e-05, 0.133982),
            (0.0173703, 0.309008, 0.30809, 4.86158e-05, 2.73027e-06, -1.47293e-06),
        ),
        LinkInertia(
            3.40713,
            (-0.184611, -3.16132e-06, 0.0207467),
            (0.00351399, 0.0757627, 0.0753326, -7.05141e-06, -0.00386449, -2.21785e-06),
        ),
        LinkInertia(
            1.02694,
            (8.21343e-05, -0.000620603, 0.102458),
            (0.00113619, 0.000835059, 0.00110592, 2.36225e-06, -1.1776e-06, -3.46388e-05),
        ),
        LinkInertia(
            0.71735,
            (1.78787e-05, -0.00342032, 0.0895761),
            (0.000921986, 0.000605477, 0.000864061, 1.07718e-07, 1.16272e-07, 1.2528e-05),
        ),
        LinkInertia(
            0.223343,
            (-7.17167e-06, -0.00182008, 0.0640205),
            (9.65841e-05, 9.27773e-05, 0.000148749, -6.26865e-09, -2.29858e-08, -2.68544e-07),
        ),
    ),
    "ur10": (
        LinkInertia(
            5.9463,
            (-1.04373e-05, -0.00807322, 0.124605),
            (0.0209517, 0.0208796, 0.0183375, 3.01137e-05, -1.34477e-05, 0.000589667),
        ),
        LinkInertia(
            13.0684,
            (-0.219374, 0.000156742, 0.174777),
            (0.0332677, 0.728854, 0.725957, -0.000302433, 0.00684124, -1.74681e-05),
        ),
        LinkInertia(
            7.27964,
            (-0.234053, -7.64051e-06, 0.0516953),
            (0.010861, 0.378646, 0.377493, 3.30608e-05, -0.00202881, 6.01117e-06),
        ),
        LinkInertia(
            0.957666,
            (3.34453e-05, -0.00345752, 0.157404),
            (0.00161903, 0.00115649, 0.00151239, -4.33149e-07, 1.46014e-06, 3.37628e-05),
        ),
        LinkInertia(
            1.45813,
            (0.000158537, 0.00492497, 0.109904),
            (0.00212317, 0.00166961, 0.00203461, -5.56178e-06, -2.50869e-06, -3.3533e-05),
        ),
        LinkInertia(
            0.189943,
            (-2.05157e-05, -0.000747291, 0.0755992),
            (0.000101714, 0.000103389, 0.000178592, 5.36768e-08, 5.11911e-08, -2.40592e-07),
        ),
    ),
    "ur3e": (
        LinkInertia(
            1.71471,
            (-1.58848e-05, -0.0107051, 0.150336),
            (0.0029907, 0.00262924, 0.00240034, 4.20197e-07, -9.85431e-07, 5.45096e-05),
        ),
        LinkInertia(
            5.3564,
            (-0.11296, -3.00587e-05, 0.11982),
            (0.00857411, 0.048142, 0.0456568, 6.8642e-06, 0.000390982, -1.25391e-05),
        ),
        LinkInertia(
            2.48905,
            (-0.118455, 7.18204e-06, 0.0340405),
            (0.00229311, 0.0147736, 0.0142058, -1.87358e-08, -0.000707483, -5.63171e-08),
        ),
        LinkInertia(
            0.776481,
            (1.11166e-05, -0.00261553, 0.120155),
            (0.00088761, 0.000605825, 0.000730735, -2.1199e-07, 2.01057e-07, 1.21865e-05),
        ),
        LinkInertia(
            0.621994,
            (-1.88297e-05, 0.00350241, 0.0817168),
            (0.000620147, 0.000365733, 0.000608208, 2.16463e-07, 3.10617e-07, -4.08515e-06),
        ),
        LinkInertia(
            0.241366,
            (-2.56846e-05, -0.000685015, 0.071209),
            (9.86266e-05, 9.3495e-05, 0.000122853, -7.48127e-08, 6.01602e-08, -6.44947e-07),
        ),
    ),
    "ur5e": (
        LinkInertia(
            2.22282,
            (0.000164284, -0.0118649, 0.162312),
            (0.00556317, 0.00502192, 0.00488774, 6.98715e-06, 1.37396e-06, 0.000131659),
        ),
        LinkInertia(
            11.0771,
            (-0.216877, 4.88853e-05, 0.135343),
            (0.0304807, 0.260649, 0.255006, 9.56897e-06, -0.00369205, -6.94153e-05),
        ),
        LinkInertia(
            5.31762,
            (-0.191179, -2.62411e-05, 0.012602),
            (0.00812566, 0.0945369, 0.0936682, -9.8055e-06, -0.00383283, -1.28305e-06),
        ),
        LinkInertia(
            0.973128,
            (2.63783e-05, 0.000153341, 0.115913),
            (0.00163449, 0.00121709, 0.0012196, 2.41965e-07, -4.32983e-07, 1.31944e-07),
        ),
        LinkInertia(
            0.754828,
            (7.57848e-05, -0.000641927, 0.0940795),
            (0.00103866, 0.000666094, 0.000985963, -6.34025e-07, 8.81517e-07, -2.10711e-06),
        ),
        LinkInertia(
            0.254411,
            (4.83587e-05, -6.04342e-05, 0.0760197),
            (0.000133679, 0.000127624, 0.000176883, -1.35968e-07, 6.83818e-08, -6.54927e-07),
        ),
    ),
    "ur10e": (
        LinkInertia(
            4.28703,
            (4.22989e-05, -0.0146, 0.18281),
            (0.0181, 0.0165527, 0.0154688, -8.17839e-06, 9.12324e-06, 0.000228348),
        ),
        LinkInertia(
            17.917,
            (-0.271636, 0.000107108, 0.175968),
            (0.0656606, 0.786272, 0.774482, 0.000236473, -0.0111113, 0.000139794),
        ),
        LinkInertia(
            8.68041,
            (-0.286495, -5.51794e-06, 0.0466385),
            (0.0170678, 0.295221, 0.292688, -4.06506e-05, -0.00372975, 3.24968e-05),
        ),
        LinkInertia(
            1.21229,
            (-2.62741e-05, -0.00581274, 0.161552),
            (0.00239136, 0.00179048, 0.00203365, 5.93236e-07, -7.07978e-07, 7.25126e-05),
        ),
        LinkInertia(
            1.06435,
            (1.4749e-05, 0.00712717, 0.11322),
            (0.00191583, 0.00133051, 0.00183321, 2.06532e-07, -5.47527e-07, -4.69812e-05),
        ),
        LinkInertia(
            0.338853,
            (-1.38667e-05, -7.98192e-05, 0.0909296),
            (0.00023363, 0.00022434, 0.000333919, 6.59514e-07, -7.216e-08, -1.0881e-06),
        ),
    ),
    "ur16e": (
        LinkInertia(
            5.20675,
            (4.22989e-05, -0.0146, 0.18281),
            (0.0219831, 0.0201038, 0.0187874, -9.93294e-06, 1.10805e-05, 0.000277337),
        ),
        LinkInertia(
            17.7337,
            (-0.208948, 2.31627e-05, 0.175734),
            (0.0648581, 0.525361, 0.513843, 2.61978e-05, -0.00884078, 7.00177e-06),
        ),
        LinkInertia(
            6.98289,
            (-0.182688, 6.56961e-05, 0.0477879),
            (0.013568, 0.10977, 0.107972, -1.36985e-06, -0.00257689, 2.48166e-05),
        ),
        LinkInertia(
            1.47237,
            (-2.62741e-05, -0.00581274, 0.161552),
            (0.00290439, 0.0021746, 0.00246995, 7.20506e-07, -8.59865e-07, 8.80691e-05),
        ),
        LinkInertia(
            1.29269,
            (1.4749e-05, 0.00712717, 0.11322),
            (0.00232685, 0.00161595, 0.0022265, 2.5084e-07, -6.64991e-07, -5.70604e-05),
        ),
        LinkInertia(
            0.411549,
            (-1.38667e-05, -7.98192e-05, 0.0909296),
            (0.000283752, 0.000272469, 0.000405557, 8.01003e-07, -8.76409e-08, -1.32154e-06),
        ),
    ),
    "ur20": (
        LinkInertia(
            9.06247,
            (9.92305e-06, -0.030054, 0.211904),
            (0.0599237, 0.0504509, 0.0516333, -1.35442e-05, -4.25265e-06, 0.00581201),
        ),
        LinkInertia(
            33.0399,
            (-0.376892, -0.000374718, 0.248391),
            (0.140561, 3.17461, 3.1511, -0.000232643, 0.01848, 1.10478e-05),
        ),
        LinkInertia(
            17.6991,
            (-0.251114, -3.58502e-05, 0.0547063),
            (0.0491293, 1.04906, 1.04172, -0.00015713, -0.0285114, 7.4924e-06),
        ),
        LinkInertia(
            1.74971,
            (-2.13491e-05, -0.0197525, 0.184511),
            (0.00413919, 0.00309375, 0.0033691, -2.4434e-07, 5.59885e-07, 0.000347623),
        ),
        LinkInertia(
            1.72718,
            (-4.56661e-05, 0.0195251, 0.143096),
            (0.00393806, 0.00303196, 0.00338654, -2.18702e-07, -3.01915e-07, -0.000403232),
        ),
        LinkInertia(
            0.721626,
            (5.01433e-07, -0.000416091, 0.119024),
            (0.000755743, 0.000740016, 0.000910129, 1.68111e-07, -2.21099e-08, 1.33244e-06),
        ),
    ),
    "ur30": (
        LinkInertia(
            11.161,
            (9.92305e-06, -0.030054, 0.211904),
            (0.0737995, 0.0621332, 0.0635894, -1.66805e-05, -5.23739e-06, 0.00715782),
        ),
        LinkInertia(
            30.7683,
            (-0.27402, -0.000244098, 0.245484),
            (0.131887, 1.89777, 1.87019, -0.000155186, 0.014621, 2.97233e-05),
        ),
        LinkInertia(
            16.4002,
            (-0.154638, 5.45437e-06, 0.0585516),
            (0.0471203, 0.547259, 0.538364, -0.000381098, -0.0193369, -1.45635e-05),
        ),
        LinkInertia(
            2.15487,
            (-2.13491e-05, -0.0197525, 0.184511),
            (0.00509765, 0.00381013, 0.00414924, -3.00918e-07, 6.89531e-07, 0.000428118),
        ),
        LinkInertia(
            2.12712,
            (-4.56661e-05, 0.0195251, 0.143096),
            (0.00484995, 0.00373404, 0.00417072, -2.69344e-07, -3.71825e-07, -0.000496603),
        ),
        LinkInertia(
            0.888723,
            (5.01433e-07, -0.000416091, 0.119024),
            (0.000930741, 0.000911372, 0.00112088, 2.07039e-07, -2.72296e-08, 1.64097e-06),
        ),
    ),
}
