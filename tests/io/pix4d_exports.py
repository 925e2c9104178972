"""A BINGO file and Pix4D's calibrated camera parameters written from their published
descriptions, independently of baarda's reader and writer: Pix4D's articles "What is the
bingo file generated during Initial Processing" (header ``name LABEL_W_H`` with the sensor
size in mm, ``point x y`` in mm from the image centre, y up, -99 after each image) and "How
are the Internal and External Camera Parameters defined" (perspective lens: R1..R3, T1, T2
on the homogeneous point in Pix4D's image frame, y up), and the calibrated camera
parameters' layout (name W H, K, radial, tangential, t, R; m = K [R | -R t] X)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

HEADER = ("fileName imageWidth imageHeight\ncamera matrix K [3x3]\nradial distortion [3x1]\n"
          "tangential distortion [2x1]\ncamera position t [3x1]\ncamera rotation R [3x3]\n"
          "camera model m = K [R|-Rt] X\n\n")


def pix4d_pixel(X, R, t, K, radial, tangential) -> np.ndarray:
    """Pixel coordinates (n, 2) [from the top-left corner, y down] of ground points X (n, 3)
    by Pix4D's perspective model."""
    Xc = (np.asarray(X) - t) @ R.T  # camera frame: x right, y down, z forward
    xh, yh = Xc[:, 0] / Xc[:, 2], -Xc[:, 1] / Xc[:, 2]  # Pix4D's image frame: y up
    r2 = xh * xh + yh * yh
    radial_factor = 1 + radial[0] * r2 + radial[1] * r2 ** 2 + radial[2] * r2 ** 3
    t1, t2 = tangential
    xd = xh * radial_factor + 2 * t1 * xh * yh + t2 * (r2 + 2 * xh * xh)
    yd = yh * radial_factor + t1 * (r2 + 2 * yh * yh) + 2 * t2 * xh * yh
    return np.column_stack([K[0, 0] * xd + K[0, 2], K[1, 2] - K[1, 1] * yd])


def rotation(omega: float, phi: float, kappa: float) -> np.ndarray:
    """A world-to-camera rotation (camera y down, looking along +z) of a roughly nadir
    camera: the camera turned by small angles."""
    def rx(a):
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    def rz(a):
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    nadir = np.diag([1.0, -1.0, -1.0])  # looking down, image y to the south
    return rz(kappa) @ rx(omega) @ rx(phi) @ nadir


def write_pix4d(folder: Path, images: list[dict], X: np.ndarray, name: str = "proj",
                label: str = "H") -> tuple[Path, dict]:
    """NAME_tp_bingo.txt and NAME_calibrated_camera_parameters.txt of images (name, W, H,
    pixel_mm, K, radial, tangential, t, R) observing the ground points X (point ids 1001..)
    that fall inside them; the BINGO file and the observations {(image, point): (x, y)}."""
    folder.mkdir(parents=True, exist_ok=True)
    bingo, cams, obs = [], [HEADER], {}
    for im in images:
        w, h, p = im["W"], im["H"], im["pixel_mm"]
        px = pix4d_pixel(X, im["R"], im["t"], im["K"], im["radial"], im["tangential"])
        bingo.append(f"{im['name']} {label}_{w * p:.10g}_{h * p:.10g}")
        for j, (u, v) in enumerate(px):
            if 0 <= u <= w and 0 <= v <= h:
                x, y = (u - w / 2) * p, (h / 2 - v) * p
                bingo.append(f"{1001 + j} {x:.8f} {y:.8f}")
                obs[(im["name"], str(1001 + j))] = (float(f"{x:.8f}"), float(f"{y:.8f}"))
        bingo.append("-99")
        K = im["K"]
        cams.append(f"{im['name']}.JPG {w} {h}\n" + "\n".join(
            " ".join(f"{v:.17g}" for v in row) for row in K) + "\n"
            + " ".join(f"{v:.17g}" for v in im["radial"]) + "\n"
            + " ".join(f"{v:.17g}" for v in im["tangential"]) + "\n"
            + " ".join(f"{v:.17g}" for v in im["t"]) + "\n"
            + "\n".join(" ".join(f"{v:.17g}" for v in row) for row in im["R"]) + "\n")
    path = folder / f"{name}_tp_bingo.txt"
    path.write_text("\n".join(bingo) + "\n")
    (folder / f"{name}_calibrated_camera_parameters.txt").write_text("".join(cams))
    return path, obs


def sample_block() -> tuple[list[dict], np.ndarray]:
    """Three images of a 5 x 4 grid of ground points from 100 m, one lens (Pix4D-like
    values), the second image with its own principal point."""
    gx, gy = np.meshgrid(np.linspace(-30, 30, 5), np.linspace(-20, 20, 4))
    X = np.column_stack([gx.ravel(), gy.ravel(), 2.0 * np.sin(gx.ravel() / 9)])
    images = []
    for k, (cx, angles) in enumerate([(-12.0, (0.01, -0.02, 0.03)),
                                      (0.0, (-0.015, 0.01, -0.02)),
                                      (12.0, (0.02, 0.005, 0.01))]):
        K = np.array([[3700.0, 0, 2010.5 + 30 * (k == 1)], [0, 3700.0, 1490.25], [0, 0, 1]])
        images.append(dict(name=f"IMG_{k:04d}", W=4000, H=3000, pixel_mm=0.00158, K=K,
                           radial=np.array([-0.12, 0.09, -0.02]),
                           tangential=np.array([0.0011, -0.0007]),
                           t=np.array([cx, 1.5 * k, 100.0 + k]), R=rotation(*angles)))
    return images, X
