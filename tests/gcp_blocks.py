"""A simulated drone block written as a COLMAP text model plus an OpenDroneMap gcp_list.txt,
projected here independently of baarda's readers: COLMAP's pinhole (x_cam = R X + t, pixel
u = fx x/z + cx, v = fy y/z + cy, the first pixel's centre at 0.5, 0.5) in a model frame that
is a similarity of the true local east-north-up frame; the GCPs in UTM zone 32N (from the
true local frame by pyproj, block/crs.LocalFrame) with pixels in ODM's convention (the first
pixel's centre at 0, 0: u_odm = u_colmap - 0.5)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from baarda.block.crs import LocalFrame
from baarda.io.colmap import matrix_to_qvec

CRS = "EPSG:32632"
ORIGIN = np.array([500_000.0, 5_400_000.0, 300.0])  # the local frame's origin in UTM 32N
W, H = 4000, 3000
FX, FY, CX, CY = 2400.0, 2412.0, 2010.3, 1495.8
HEIGHT = 120.0  # flying height [m]
# the COLMAP model's frame: x_model = S Q x_local + T
S = 0.37
T = np.array([3.0, -2.0, 5.0])


def _rot(a: float, b: float, c: float) -> np.ndarray:
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    return rz @ ry @ rx


Q = _rot(0.3, -0.2, 1.1)


@dataclass
class GcpBlock:
    frame: LocalFrame
    centres: np.ndarray  # (n, 3) local
    rot: np.ndarray  # (n, 3, 3) world(local)-to-camera, COLMAP axes (x right, y down, z fwd)
    ties: np.ndarray  # (k, 3) local
    gcps: np.ndarray  # (8, 3) local
    gcp_names: list[str]

    def project(self, xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """COLMAP pixels (n_photos, n_points, 2) of local points and a mask of those inside
        the image and in front."""
        cam = np.einsum("nij,nkj->nki", self.rot, xyz[None, :, :] - self.centres[:, None, :])
        z = cam[..., 2]
        u = FX * cam[..., 0] / z + CX
        v = FY * cam[..., 1] / z + CY
        uv = np.stack([u, v], -1)
        inside = (z > 0) & (u > 20) & (u < W - 20) & (v > 20) & (v < H - 20)
        return uv, inside

    def model_pose(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """(qvec, tvec) of photo i in the model frame (x_model = S Q x + T)."""
        r = self.rot[i] @ Q.T  # S x_cam = R Q^T (x_m - T) - S R C
        c_m = S * Q @ self.centres[i] + T
        return matrix_to_qvec(r), -r @ c_m  # the camera frame in model units (scale S)

    def to_model(self, xyz: np.ndarray) -> np.ndarray:
        return S * xyz @ Q.T + T


def gcp_block(seed: int = 0, strips: int = 2, per_strip: int = 5) -> GcpBlock:
    rng = np.random.default_rng(seed)
    xs = np.arange(per_strip) * 40.0
    ys = np.arange(strips) * 60.0
    centres = np.array([(x, y, HEIGHT) for y in ys for x in xs])
    rot = np.array([np.diag([1.0, -1.0, -1.0]) @ _rot(*rng.normal(0, 0.02, 3)).T
                    for _ in centres])  # looking down, x east, y south on the image
    lo, hi = np.array([-40.0, -40.0]), np.array([xs[-1] + 40, ys[-1] + 40])
    ties = np.column_stack([rng.uniform(lo[0], hi[0], 160), rng.uniform(lo[1], hi[1], 160),
                            rng.normal(0, 3, 160)])
    gx = np.array([0.1, 0.5, 0.9, 0.1, 0.9, 0.1, 0.5, 0.9]) * (hi[0] - lo[0] - 60) + lo[0] + 30
    gy = np.array([0.0, 0.0, 0.0, 0.5, 0.5, 1.0, 1.0, 1.0]) * (hi[1] - lo[1] - 60) + lo[1] + 30
    gcps = np.column_stack([gx, gy, rng.normal(0, 2, 8)])
    frame = LocalFrame(CRS, ORIGIN)
    return GcpBlock(frame, centres, rot, ties, gcps, [f"GCP{k + 1}" for k in range(8)])


def write_colmap_text(b: GcpBlock, folder: Path, rng: np.random.Generator,
                      sigma_px: float = 1.0) -> None:
    """cameras.txt, images.txt, points3D.txt of the block: tie points seen on two or more
    photos, keypoints with noise sigma_px."""
    uv, inside = b.project(b.ties)
    keep = inside.sum(axis=0) >= 2
    ties_m = b.to_model(b.ties[keep])
    uv, inside = uv[:, keep], inside[:, keep]
    noisy = uv + rng.normal(0, sigma_px, uv.shape)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "cameras.txt").write_text(
        f"# Camera list\n1 PINHOLE {W} {H} {FX!r} {FY!r} {CX!r} {CY!r}\n")
    lines = ["# Image list"]
    track: dict[int, list[str]] = {j: [] for j in range(len(ties_m))}
    for i in range(len(b.centres)):
        q, t = b.model_pose(i)
        lines.append(f"{i + 1} " + " ".join(repr(float(v)) for v in (*q, *t))
                     + f" 1 IMG_{i:04d}.JPG")
        kps = []
        for k, j in enumerate(np.flatnonzero(inside[i])):
            kps.append(f"{float(noisy[i, j, 0])!r} {float(noisy[i, j, 1])!r} {j + 1}")
            track[j].append(f"{i + 1} {k}")
        lines.append(" ".join(kps))
    (folder / "images.txt").write_text("\n".join(lines) + "\n")
    pts = ["# 3D point list"]
    for j, x in enumerate(ties_m):
        pts.append(f"{j + 1} " + " ".join(repr(float(v)) for v in x) + " 128 128 128 0.5 "
                   + " ".join(track[j]))
    (folder / "points3D.txt").write_text("\n".join(pts) + "\n")


def gcp_lines(b: GcpBlock, rng: np.random.Generator, sigma_px: float = 1.0,
              sigma_m: float = 0.05, error: tuple[str, str, float, float] | None = None,
              xyz_noise: bool = True) -> tuple[list[str], list[tuple[str, str]]]:
    """(the lines of a gcp_list.txt in UTM 32N, the (gcp, image) of each measurement line);
    `error`: (gcp, image, du, dv) pixels added to that measurement."""
    uv, inside = b.project(b.gcps)
    xyz = b.gcps + (rng.normal(0, sigma_m, b.gcps.shape) if xyz_noise else 0.0)
    utm = b.frame.from_local(xyz)
    out = ["WGS84 UTM 32N"]
    which = []
    for k, name in enumerate(b.gcp_names):
        for i in np.flatnonzero(inside[:, k]):
            u, v = uv[i, k] - 0.5 + rng.normal(0, sigma_px, 2)
            image = f"IMG_{i:04d}.JPG"
            if error is not None and (name, image) == error[:2]:
                u, v = u + error[2], v + error[3]
            out.append(" ".join(repr(float(t)) for t in (*utm[k], u, v)) + f" {image} {name}")
            which.append((name, image))
    return out, which
