"""Hand-eye calibration: the camera's pose from arm poses and board views.

Eye-in-hand (camera on the flange, board fixed): for every view i,
``T_world_flange[i] @ X @ T_camera_board[i] = Z`` with X = T_flange_camera and
Z = T_world_board unknown. Eye-to-hand (camera fixed, board on the flange):
``C @ T_camera_board[i] = T_world_flange[i] @ Y`` with C = T_world_camera and
Y = T_flange_board.

OpenCV's ``calibrateHandEye`` (Park) gives the first estimate; a least-squares fit of
every detected corner's pixel (scipy) then refines both unknowns together. The residual is
reported in pixels and as how far each view's board pose lands from the common one (mm,
deg). Poses that turn the camera about too few axes leave the solution unobservable: they
are refused before solving (:func:`conditioning`), as is a fit whose uncertainty is large.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import OptimizeResult, least_squares
from scipy.spatial.transform import Rotation

from cellrunner.errors import CellrunnerError
from cellrunner.model.geometry import invert
from cellrunner.vision.board import BoardView, cv2

#: fewest views with the board found
MIN_VIEWS = 6
#: the relative turns between views must span two axes, each by at least this much (deg)
MIN_TURN_SPREAD_DEG = 8.0
#: refuse a fit whose 1-sigma uncertainty is above these (m, deg)
MAX_SIGMA_M, MAX_SIGMA_DEG = 0.0005, 0.1
#: refuse a fit whose corners reproject worse than this (rms, px)
MAX_RMS_PX = 1.0


class CalibrationError(CellrunnerError):
    """The views cannot give a trustworthy camera pose (the message says why)."""


@dataclass(frozen=True)
class HandEye:
    """The solved camera pose and how well it fits.

    ``T_mount_camera``: T_flange_camera (eye-in-hand) or T_world_camera (eye-to-hand);
    ``T_mount_board``: T_world_board or T_flange_board."""

    eye_in_hand: bool
    T_mount_camera: np.ndarray
    T_mount_board: np.ndarray
    rms_px: float
    spread_m: float  # rms distance of each view's board pose from the solved one
    spread_deg: float
    sigma_m: float  # 1-sigma uncertainty of the camera position (largest axis)
    sigma_deg: float  # ... and of its orientation
    views: int


def _pose(x: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(x[:3]).as_matrix()
    T[:3, 3] = x[3:]
    return T


def _vec(T: np.ndarray) -> np.ndarray:
    return np.concatenate([Rotation.from_matrix(T[:3, :3]).as_rotvec(), T[:3, 3]])


def _angle_deg(R: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1.0, 1.0))))


def conditioning(T_world_flange: list[np.ndarray]) -> tuple[float, float]:
    """The two largest singular values (deg) of the arm's turns between views: hand-eye
    needs turns about at least two different axes (the second value well above zero)."""
    R0 = T_world_flange[0][:3, :3]
    turns = [Rotation.from_matrix(R0.T @ T[:3, :3]).as_rotvec() for T in T_world_flange[1:]]
    s = np.linalg.svd(np.degrees(np.array(turns)), compute_uv=False)
    return float(s[0]), float(s[1]) if len(s) > 1 else 0.0


def _camera_board(eye_in_hand: bool, F: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """T_camera_board of a view at flange pose F, given the unknowns A (the camera in its
    mount) and B (the board in its mount)."""
    if eye_in_hand:
        return np.asarray(invert(F @ A) @ B)
    return np.asarray(invert(A) @ F @ B)


def solve(
    eye_in_hand: bool,
    T_world_flange: list[np.ndarray],
    views: list[BoardView],
    K: np.ndarray,
    distortion: np.ndarray,
) -> HandEye:
    """The camera pose from views (each taken with the flange at ``T_world_flange[i]``)."""
    if len(views) < MIN_VIEWS:
        raise CalibrationError(
            f"the board was found in {len(views)} views; calibration needs at least {MIN_VIEWS}"
        )
    first, second = conditioning(T_world_flange)
    if second < MIN_TURN_SPREAD_DEG:
        raise CalibrationError(
            f"the views turn the camera about too few axes (turn spread {first:.1f} and "
            f"{second:.1f} deg; needs {MIN_TURN_SPREAD_DEG:g} deg about a second axis): "
            "tilt the views about two different axes"
        )
    A, B = _initial(eye_in_hand, T_world_flange, views)
    A, B, result = _refine(eye_in_hand, T_world_flange, views, K, distortion, A, B)
    n = len(result.fun) // 2
    rms = float(np.sqrt(np.mean(result.fun.reshape(n, 2) ** 2) * 2))
    sigma_m, sigma_deg = _sigma(result, rms)
    spread_m, spread_deg = _spread(eye_in_hand, T_world_flange, views, A, B)
    return HandEye(eye_in_hand, A, B, rms, spread_m, spread_deg, sigma_m, sigma_deg, len(views))


def check_fit(fit: HandEye) -> None:
    """Refuse a fit that reprojects badly or whose camera pose is poorly determined."""
    if fit.rms_px > MAX_RMS_PX:
        raise CalibrationError(
            f"the corners reproject {fit.rms_px:.2f} px rms (at most {MAX_RMS_PX:g}): check "
            "the intrinsics, the board's square and marker sizes, and that nothing moved"
        )
    if fit.sigma_m > MAX_SIGMA_M or fit.sigma_deg > MAX_SIGMA_DEG:
        raise CalibrationError(
            f"the camera pose is poorly determined (1-sigma {fit.sigma_m * 1000:.2f} mm, "
            f"{fit.sigma_deg:.3f} deg; at most {MAX_SIGMA_M * 1000:g} mm, {MAX_SIGMA_DEG:g} "
            "deg): use more views, tilted further"
        )


def _initial(
    eye_in_hand: bool, T_world_flange: list[np.ndarray], views: list[BoardView]
) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's closed form (Park): X from the flange and board motions, then the board."""
    cv = cv2()
    robot = T_world_flange if eye_in_hand else [invert(T) for T in T_world_flange]
    R, t = cv.calibrateHandEye(
        [T[:3, :3] for T in robot],
        [T[:3, 3] for T in robot],
        [v.T_camera_board[:3, :3] for v in views],
        [v.T_camera_board[:3, 3] for v in views],
        method=cv.CALIB_HAND_EYE_PARK,
    )
    A = np.eye(4)
    A[:3, :3], A[:3, 3] = R, np.ravel(t)
    # each view's estimate of the board in its mount; their mean is the first guess
    if eye_in_hand:
        guesses = [F @ A @ v.T_camera_board for F, v in zip(T_world_flange, views, strict=True)]
    else:
        guesses = [
            invert(F) @ A @ v.T_camera_board for F, v in zip(T_world_flange, views, strict=True)
        ]
    mean_R = Rotation.from_matrix([G[:3, :3] for G in guesses]).mean().as_matrix()
    B = np.eye(4)
    B[:3, :3], B[:3, 3] = mean_R, np.mean([G[:3, 3] for G in guesses], axis=0)
    return A, B


def _refine(
    eye_in_hand: bool,
    T_world_flange: list[np.ndarray],
    views: list[BoardView],
    K: np.ndarray,
    distortion: np.ndarray,
    A: np.ndarray,
    B: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, OptimizeResult]:
    cv = cv2()

    def residuals(x: np.ndarray) -> np.ndarray:
        Ax, Bx = A @ _pose(x[:6]), B @ _pose(x[6:])
        out = []
        for F, view in zip(T_world_flange, views, strict=True):
            T = _camera_board(eye_in_hand, F, Ax, Bx)
            rvec = Rotation.from_matrix(T[:3, :3]).as_rotvec()
            projected, _ = cv.projectPoints(view.points_board_m, rvec, T[:3, 3], K, distortion)
            out.append((projected.reshape(-1, 2) - view.pixels).ravel())
        return np.concatenate(out)

    result = least_squares(residuals, np.zeros(12), method="lm", x_scale="jac")
    return A @ _pose(result.x[:6]), B @ _pose(result.x[6:]), result


def _sigma(result: OptimizeResult, rms_px: float) -> tuple[float, float]:
    """1-sigma of the camera's position (m) and orientation (deg), largest axis, from the
    fit's Jacobian and its pixel noise."""
    J = result.jac
    try:
        cov = np.linalg.inv(J.T @ J) * rms_px**2
    except np.linalg.LinAlgError:
        return float("inf"), float("inf")
    var = np.clip(np.diag(cov)[:6], 0.0, None)
    return float(np.sqrt(var[3:].max())), float(np.degrees(np.sqrt(var[:3].max())))


def _spread(
    eye_in_hand: bool,
    T_world_flange: list[np.ndarray],
    views: list[BoardView],
    A: np.ndarray,
    B: np.ndarray,
) -> tuple[float, float]:
    """RMS of how far each view's own board pose lands from the solved one (m, deg)."""
    d_m, d_deg = [], []
    for F, view in zip(T_world_flange, views, strict=True):
        G = F @ A @ view.T_camera_board if eye_in_hand else invert(F) @ A @ view.T_camera_board
        D = invert(B) @ G
        d_m.append(np.linalg.norm(D[:3, 3]))
        d_deg.append(_angle_deg(D[:3, :3]))
    return float(np.sqrt(np.mean(np.square(d_m)))), float(np.sqrt(np.mean(np.square(d_deg))))
