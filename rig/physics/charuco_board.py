"""The ChArUco calibration board of `rig calibrate geometry` (docs/geometry-calibration.md): its layout, where
its chessboard corners lie on the sample holder, and the OpenCV board that draws and detects it.

The board lies on the sample holder in place of a sample, its centre on the holder's centre and its rows along
the sample's x mark. OpenCV's board coordinates have x along a row, y down the columns (as the board is drawn)
and z into the board; the sample coordinate system (docs/geometry.md) has z out of the surface, so a board point
(x, y) is the sample point (x − width/2, height/2 − y, 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

#: The ArUco dictionaries a board may use (OpenCV's predefined ones of 4×4 to 6×6 bits).
DICTIONARIES = tuple(f"DICT_{bits}X{bits}_{n}" for bits in (4, 5, 6) for n in (50, 100, 250, 1000))


class BoardError(ValueError):
    """A board layout that cannot be drawn or detected; the message names the field."""


@dataclass(frozen=True)
class BoardLayout:
    """Squares across (along sample x) and down, the square's and the marker's side (m), the ArUco dictionary."""

    squares_x: int = 9
    squares_y: int = 7
    square_m: float = 0.02
    marker_m: float = 0.012
    dictionary: str = "DICT_4X4_50"

    def __post_init__(self) -> None:
        if not (3 <= self.squares_x <= 40 and 3 <= self.squares_y <= 40):
            raise BoardError(f"squares {self.squares_x}×{self.squares_y}: each must be 3 … 40")
        if not (0 < self.square_m <= 1 and np.isfinite(self.square_m)):
            raise BoardError(f"square_m {self.square_m!r}: must be a side in metres, 0 … 1")
        if not 0 < self.marker_m < self.square_m:
            raise BoardError(f"marker_m {self.marker_m!r}: must be positive and smaller than square_m")
        if self.dictionary not in DICTIONARIES:
            raise BoardError(f"dictionary {self.dictionary!r}: one of {', '.join(DICTIONARIES)}")
        markers = (self.squares_x * self.squares_y) // 2
        if markers > int(self.dictionary.rsplit("_", 1)[1]):
            raise BoardError(f"{self.squares_x}×{self.squares_y} squares need {markers} markers, more than "
                             f"{self.dictionary} has")

    @property
    def size_m(self) -> tuple[float, float]:
        return self.squares_x * self.square_m, self.squares_y * self.square_m

    def cv2_board(self) -> cv2.aruco.CharucoBoard:
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard((self.squares_x, self.squares_y), self.square_m, self.marker_m, dictionary)

    def board_points(self) -> np.ndarray:
        """(N, 3) chessboard corners in OpenCV's board coordinates (m), indexed by corner id."""
        return np.asarray(self.cv2_board().getChessboardCorners(), float).reshape(-1, 3)

    def sample_points(self) -> np.ndarray:
        """(N, 3) chessboard corners in the sample coordinate system (m), indexed by corner id."""
        return to_sample(self.board_points(), self.size_m)

    def bitmap(self, px_per_square: int) -> np.ndarray:
        """The printed board (uint8, 0 black … 255 white), `px_per_square` pixels a square side; pixel edges at
        integers, so board point (x, y) is bitmap point (x, y) · px_per_square / square_m."""
        size = (self.squares_x * px_per_square, self.squares_y * px_per_square)
        return self.cv2_board().generateImage(size, marginSize=0, borderBits=1)

    def scene(self) -> str:
        """The board as a simulated camera's `SCENE board ...` request spells it (docs/sim-camera-protocol.md)."""
        return (f"board {self.squares_x} {self.squares_y} {self.square_m!r} {self.marker_m!r} "
                f"{self.dictionary}")

    @classmethod
    def from_scene(cls, words: list[str]) -> BoardLayout:
        """The inverse of `scene` (without its first word); BoardError naming what is wrong."""
        if len(words) != 5:
            raise BoardError("board takes <squares_x> <squares_y> <square_m> <marker_m> <dictionary>")
        try:
            return cls(int(words[0]), int(words[1]), float(words[2]), float(words[3]), words[4])
        except ValueError as exc:
            raise BoardError(f"board {' '.join(words)}: {exc}") from None


def to_sample(board_points: np.ndarray, size_m: tuple[float, float]) -> np.ndarray:
    """OpenCV board coordinates (..., 3) → sample coordinates (module docstring)."""
    p = np.asarray(board_points, float)
    return np.stack([p[..., 0] - size_m[0] / 2, size_m[1] / 2 - p[..., 1], -p[..., 2]], axis=-1)
