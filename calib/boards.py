"""Calibration targets: checkerboards and ChArUco boards, their 3D corner layout and their detection."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from calib.errors import CalibrationError

__all__ = ["CheckerBoard", "CharucoBoard", "Board", "detect_board", "board_image"]


def _pos_int(name: str, value: Any, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise CalibrationError(f"`{name}` must be an int >= {minimum}, got {value!r}")
    return int(value)


def _pos_float(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not (
        np.isfinite(value) and value > 0
    ):
        raise CalibrationError(f"`{name}` must be a finite number > 0 (metres), got {value!r}")
    return float(value)


@dataclass(frozen=True)
class CheckerBoard:
    """A plain checkerboard.

    Parameters
    ----------
    cols, rows : int >= 2
        Inner corners per row and per column (a board of 10 x 7 squares has 9 x 6 inner corners). They must
        differ, else the board's orientation is ambiguous.
    square_m : float > 0
        Side of one square, metres (this sets the unit of the calibrated ``T``).
    """

    cols: int
    rows: int
    square_m: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "cols", _pos_int("cols", self.cols, 2))
        object.__setattr__(self, "rows", _pos_int("rows", self.rows, 2))
        object.__setattr__(self, "square_m", _pos_float("square_m", self.square_m))
        if self.cols == self.rows:
            raise CalibrationError(f"`cols` and `rows` must differ (a square {self.cols}x{self.rows} corner grid has an ambiguous orientation)")

    @property
    def object_points(self) -> np.ndarray:
        """``(cols*rows, 3) float32`` corner positions in the board frame, metres, row by row, z = 0."""
        grid = np.mgrid[0 : self.cols, 0 : self.rows].T.reshape(-1, 2).astype(np.float32)
        return np.hstack([grid * self.square_m, np.zeros((len(grid), 1), np.float32)]).astype(np.float32)

    def describe(self) -> str:
        return f"checkerboard {self.cols}x{self.rows} inner corners, {self.square_m * 1000:g} mm squares"


@dataclass(frozen=True)
class CharucoBoard:
    """A ChArUco board (``cv2.aruco.CharucoBoard``).

    Parameters
    ----------
    squares_x, squares_y : int >= 2
        Number of squares across and down.
    square_m, marker_m : float > 0, metres
        Side of a square and of a marker (``marker_m < square_m``).
    dictionary : str
        Name of a predefined ArUco dictionary, e.g. ``"DICT_5X5_100"``.
    legacy : bool
        Boards made before OpenCV 4.6 with an even number of rows use the legacy pattern.
    """

    squares_x: int
    squares_y: int
    square_m: float
    marker_m: float
    dictionary: str = "DICT_5X5_100"
    legacy: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "squares_x", _pos_int("squares_x", self.squares_x, 2))
        object.__setattr__(self, "squares_y", _pos_int("squares_y", self.squares_y, 2))
        object.__setattr__(self, "square_m", _pos_float("square_m", self.square_m))
        object.__setattr__(self, "marker_m", _pos_float("marker_m", self.marker_m))
        if self.marker_m >= self.square_m:
            raise CalibrationError(f"`marker_m` ({self.marker_m}) must be smaller than `square_m` ({self.square_m})")
        if not isinstance(self.dictionary, str) or not self.dictionary.startswith("DICT_") or not hasattr(cv2.aruco, self.dictionary):
            raise CalibrationError(f"`dictionary` must name a cv2.aruco predefined dictionary such as 'DICT_5X5_100', got {self.dictionary!r}")
        n_markers = (self.squares_x * self.squares_y) // 2
        capacity = int(self.dictionary.rsplit("_", 1)[-1]) if self.dictionary.rsplit("_", 1)[-1].isdigit() else None
        if capacity is not None and n_markers > capacity:
            raise CalibrationError(f"`dictionary` {self.dictionary} has {capacity} markers, the board needs {n_markers}")

    def cv_board(self) -> Any:
        """The ``cv2.aruco.CharucoBoard``."""
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        board = cv2.aruco.CharucoBoard((self.squares_x, self.squares_y), self.square_m, self.marker_m, dictionary)
        board.setLegacyPattern(bool(self.legacy))
        return board

    def describe(self) -> str:
        return (f"ChArUco {self.squares_x}x{self.squares_y} squares, {self.square_m * 1000:g} mm squares, "
                f"{self.marker_m * 1000:g} mm markers, {self.dictionary}")


Board = CheckerBoard | CharucoBoard


def _gray(image: np.ndarray, name: str) -> np.ndarray:
    image = np.asarray(image)
    if image.dtype != np.uint8:
        raise CalibrationError(f"`{name}` must be a uint8 image, got dtype {image.dtype}")
    if image.ndim == 3 and image.shape[2] in (3, 4):
        return cv2.cvtColor(image[..., :3], cv2.COLOR_BGR2GRAY)
    if image.ndim == 3 and image.shape[2] == 1:
        return image[..., 0]
    if image.ndim != 2 or min(image.shape) < 8:
        raise CalibrationError(f"`{name}` must be an (H, W) or (H, W, 3) image, got shape {image.shape}")
    return image


def detect_board(image: np.ndarray, board: Board, *, name: str = "image") -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Find a calibration board in one image.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) uint8
    board : CheckerBoard or CharucoBoard

    Returns
    -------
    (ids, object_points, image_points) or None when the board is not found
        ``ids`` (N,) int corner ids, ``object_points`` (N, 3) float32 metres, ``image_points`` (N, 2) float32
        pixels (sub-pixel refined). A checkerboard gives all corners, a ChArUco board the ones it sees (>= 6).
    """
    gray = _gray(image, name)
    if isinstance(board, CheckerBoard):
        pattern = (board.cols, board.rows)
        flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
        try:
            found, corners = cv2.findChessboardCorners(gray, pattern, flags=flags)
        except cv2.error:  # e.g. images too small for its adaptive threshold: no board there
            return None
        if not found or corners is None or len(corners) != board.cols * board.rows:
            return None
        corners = corners.reshape(-1, 2).astype(np.float32)
        spacing = float(np.min(np.linalg.norm(np.diff(corners.reshape(board.rows, board.cols, 2), axis=1), axis=-1)))
        half = int(np.clip(spacing * 0.4, 2, 11))
        corners = cv2.cornerSubPix(gray, corners.reshape(-1, 1, 2), (half, half), (-1, -1),
                                   (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-4)).reshape(-1, 2)
        # A checkerboard with cols != rows is symmetric under a 180 degree turn: put the first corner at the top-left
        # so that both cameras order the corners the same way.
        if float(np.dot(corners[-1] - corners[0], (1.0, 1.0))) < 0:
            corners = corners[::-1].copy()
        ids = np.arange(len(corners))
        return ids, board.object_points, corners.astype(np.float32)
    if isinstance(board, CharucoBoard):
        cv_board = board.cv_board()
        detector = cv2.aruco.CharucoDetector(cv_board)
        try:
            corners, ids, _marker_corners, _marker_ids = detector.detectBoard(gray)
        except cv2.error:
            return None
        if corners is None or ids is None or len(ids) < 6:
            return None
        ids = ids.reshape(-1).astype(np.int64)
        all_obj = np.asarray(cv_board.getChessboardCorners(), dtype=np.float32).reshape(-1, 3)
        return ids, all_obj[ids], corners.reshape(-1, 2).astype(np.float32)
    raise CalibrationError(f"`board` must be a CheckerBoard or CharucoBoard, got {type(board).__name__}")


def board_image(board: Board, *, px_per_square: int = 64) -> tuple[np.ndarray, float, tuple[float, float]]:
    """A printable picture of the board with a white margin of one square.

    Returns
    -------
    image : (H, W) uint8
    px_per_m : float
        Image pixels per metre of board.
    origin_px : (x, y)
        Continuous image coordinates (pixel centres at integers) of the board frame's origin.
    """
    px_per_square = _pos_int("px_per_square", px_per_square, 4)
    if isinstance(board, CheckerBoard):
        nx, ny = board.cols + 1, board.rows + 1
        cells = (np.add.outer(np.arange(ny), np.arange(nx)) % 2 == 0)
        squares = np.where(cells, 0, 255).astype(np.uint8)
        squares = np.kron(squares, np.ones((px_per_square, px_per_square), np.uint8))
        img = np.pad(squares, px_per_square, constant_values=255)
        # first inner corner: two squares in from the picture's corner (margin + first square)
        origin = (2 * px_per_square - 0.5, 2 * px_per_square - 0.5)
        return img, px_per_square / board.square_m, origin
    if isinstance(board, CharucoBoard):
        size = (board.squares_x * px_per_square, board.squares_y * px_per_square)
        squares = board.cv_board().generateImage(size, marginSize=0, borderBits=1)
        img = np.pad(squares, px_per_square, constant_values=255)
        origin = (px_per_square - 0.5, px_per_square - 0.5)
        return img, px_per_square / board.square_m, origin
    raise CalibrationError(f"`board` must be a CheckerBoard or CharucoBoard, got {type(board).__name__}")
