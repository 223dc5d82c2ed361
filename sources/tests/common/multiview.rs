//! Calibrated cameras and a 3D reference triangulated from several views' 2D landmarks: the
//! geometry the vision tests judge 3D, bone directions and left/right labels with. Included by
//! path in the vision tests. Two calibration formats are read.
//!
//! A Qualisys export (`*.qca.txt`, as the pose2sim demo ships it): per
//! camera its position (mm) and a rotation whose rows are the camera's axes in the world with
//! y and z pointing up and backwards (Qualisys' convention; OpenCV's camera looks along +z with
//! y down, a half turn about x away), its focal length and principal point in 1/64 pixel of the
//! calibrated picture (`fov_video`), and Brown distortion (k1, k2, p1, p2). A video whose size
//! differs from the calibrated picture holds it scaled to fit and padded evenly (the demo's
//! cameras 1 and 2: 1088×1920 scaled to 1080 wide, 7 black rows above and below).
//!
//! A caliscope `camera_array.toml` (as the shared data's desk set ships it): per camera
//! `[cameras.ID]` its OpenCV intrinsic `matrix`, `distortions` (k1, k2, p1, p2, k3), and the
//! world → camera `rotation` and `translation` (x_cam = R·x + t, metres), the calibrated
//! picture's `size`; a camera marked `ignore` is left out.
#![allow(dead_code)]

use glam::{DMat3, DVec2, DVec3, DVec4};

/// One calibrated camera.
#[derive(Clone, Debug)]
pub struct Camera {
    /// The camera's name in the calibration (`serial`: the demo's video file stems).
    pub name: String,
    /// World → camera rotation, OpenCV axes (x right, y down, z forward).
    pub rot: DMat3,
    /// Camera centre in the world, metres.
    pub pos: DVec3,
    focal: DVec2,
    centre: DVec2,
    /// k1, k2, p1, p2, k3.
    dist: [f64; 5],
    /// The calibrated picture's size in pixels.
    pub size: DVec2,
}

/// The value of `name="…"` in one XML tag's text.
fn attr(tag: &str, name: &str) -> Result<f64, String> {
    let key = format!(" {name}=\"");
    let start = tag
        .find(&key)
        .ok_or_else(|| format!("no {name} in {}", &tag[..tag.len().min(40)]))?
        + key.len();
    let len = tag[start..].find('"').ok_or("unterminated attribute")?;
    tag[start..start + len]
        .parse()
        .map_err(|e| format!("{name}: {e}"))
}

/// The text of the first `<name …>` tag in `block`.
fn tag<'a>(block: &'a str, name: &str) -> Result<&'a str, String> {
    let start = block
        .find(&format!("<{name} "))
        .ok_or_else(|| format!("no <{name}> tag"))?;
    let len = block[start..].find('>').ok_or("unterminated tag")?;
    Ok(&block[start..start + len])
}

/// The cameras of a Qualisys calibration export.
pub fn read_qca(text: &str) -> Result<Vec<Camera>, String> {
    let mut cameras = Vec::new();
    for block in text.split("<camera ").skip(1) {
        let head = &block[..block.find('>').ok_or("unterminated camera tag")?];
        let serial = head
            .split("serial=\"")
            .nth(1)
            .and_then(|s| s.split('"').next())
            .ok_or("camera without serial")?;
        let (t, k, fov) = (
            tag(block, "transform")?,
            tag(block, "intrinsic")?,
            tag(block, "fov_video")?,
        );
        let r = |i: usize, j: usize| attr(t, &format!("r{i}{j}"));
        // Rows of the rotation are the camera's axes; the half turn about x gives OpenCV's.
        let rows = DMat3::from_cols(
            DVec3::new(r(1, 1)?, r(2, 1)?, r(3, 1)?),
            DVec3::new(r(1, 2)?, r(2, 2)?, r(3, 2)?),
            DVec3::new(r(1, 3)?, r(2, 3)?, r(3, 3)?),
        );
        let rot = DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0)) * rows;
        let origin = DVec2::new(attr(fov, "left")?, attr(fov, "top")?);
        let size = DVec2::new(attr(fov, "right")?, attr(fov, "bottom")?) - origin + 1.0;
        cameras.push(Camera {
            name: serial.to_string(),
            rot,
            pos: DVec3::new(attr(t, "x")?, attr(t, "y")?, attr(t, "z")?) / 1000.0,
            focal: DVec2::new(attr(k, "focalLengthU")?, attr(k, "focalLengthV")?) / 64.0,
            centre: DVec2::new(attr(k, "centerPointU")?, attr(k, "centerPointV")?) / 64.0 - origin,
            dist: [
                attr(k, "radialDistortion1")?,
                attr(k, "radialDistortion2")?,
                attr(k, "tangentalDistortion1")?,
                attr(k, "tangentalDistortion2")?,
                0.0,
            ],
            size,
        });
    }
    if cameras.is_empty() {
        return Err("no cameras in the calibration".into());
    }
    Ok(cameras)
}

/// `value` as a list of numbers, or an error naming `what`.
fn numbers(value: Option<&toml::Value>, what: &str) -> Result<Vec<f64>, String> {
    value
        .and_then(toml::Value::as_array)
        .ok_or_else(|| format!("no {what}"))?
        .iter()
        .map(|v| {
            v.as_float()
                .or_else(|| v.as_integer().map(|i| i as f64))
                .ok_or_else(|| format!("{what}: {v} is not a number"))
        })
        .collect()
}

/// `value` as a `rows`×`cols` matrix (rows of numbers), or an error naming `what`.
fn matrix(value: Option<&toml::Value>, what: &str, rows: usize) -> Result<Vec<Vec<f64>>, String> {
    let out: Vec<Vec<f64>> = value
        .and_then(toml::Value::as_array)
        .ok_or_else(|| format!("no {what}"))?
        .iter()
        .map(|row| numbers(Some(row), what))
        .collect::<Result<_, _>>()?;
    if out.len() != rows || out.iter().any(|r| r.len() != 3) {
        return Err(format!("{what} is not {rows}x3"));
    }
    Ok(out)
}

/// The cameras of a caliscope `camera_array.toml`, named `cam_ID`, sorted by id.
pub fn read_caliscope(text: &str) -> Result<Vec<Camera>, String> {
    let doc: toml::Table = text.parse().map_err(|e| format!("{e}"))?;
    let table = doc
        .get("cameras")
        .and_then(toml::Value::as_table)
        .ok_or("no [cameras.*] tables")?;
    let mut cameras = Vec::new();
    for (id, cam) in table {
        if cam.get("ignore").and_then(toml::Value::as_bool) == Some(true) {
            continue;
        }
        let what = |field: &str| format!("camera {id}: {field}");
        let k = matrix(cam.get("matrix"), &what("matrix"), 3)?;
        let r = matrix(cam.get("rotation"), &what("rotation"), 3)?;
        let t = numbers(cam.get("translation"), &what("translation"))?;
        let size = numbers(cam.get("size"), &what("size"))?;
        let mut dist = numbers(cam.get("distortions"), &what("distortions"))?;
        if t.len() != 3 || size.len() != 2 || dist.len() > 5 {
            return Err(what("translation, size or distortions of the wrong length"));
        }
        dist.resize(5, 0.0);
        // Rows of R are the camera's axes in the world; the camera sits at -Rᵀ·t.
        let rot = DMat3::from_cols(
            DVec3::new(r[0][0], r[1][0], r[2][0]),
            DVec3::new(r[0][1], r[1][1], r[2][1]),
            DVec3::new(r[0][2], r[1][2], r[2][2]),
        );
        cameras.push(Camera {
            name: format!("cam_{id}"),
            rot,
            pos: -(rot.transpose() * DVec3::new(t[0], t[1], t[2])),
            focal: DVec2::new(k[0][0], k[1][1]),
            centre: DVec2::new(k[0][2], k[1][2]),
            dist: [dist[0], dist[1], dist[2], dist[3], dist[4]],
            size: DVec2::new(size[0], size[1]),
        });
    }
    if cameras.is_empty() {
        return Err("no cameras in the calibration".into());
    }
    cameras.sort_by(|a, b| (a.name.len(), &a.name).cmp(&(b.name.len(), &b.name)));
    Ok(cameras)
}

impl Camera {
    /// The world's up as this camera sees it (its picture's up), in world axes.
    pub fn up(&self) -> DVec3 {
        -(self.rot.transpose() * DVec3::Y)
    }

    /// The scale and padding that fit the calibrated picture into a video of `video` pixels.
    fn letterbox(&self, video: DVec2) -> (f64, DVec2) {
        let scale = (video.x / self.size.x).min(video.y / self.size.y);
        (scale, (video - self.size * scale) * 0.5)
    }

    fn distort(&self, n: DVec2) -> DVec2 {
        let [k1, k2, p1, p2, k3] = self.dist;
        let r2 = n.length_squared();
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        n * radial
            + DVec2::new(
                2.0 * p1 * n.x * n.y + p2 * (r2 + 2.0 * n.x * n.x),
                p1 * (r2 + 2.0 * n.y * n.y) + 2.0 * p2 * n.x * n.y,
            )
    }

    /// A pixel of a video of `video` pixels as a normalised, undistorted image point (the
    /// direction x/z, y/z in the camera).
    pub fn ray(&self, video: DVec2, pixel: DVec2) -> DVec2 {
        let (scale, pad) = self.letterbox(video);
        let target = ((pixel - pad) / scale - self.centre) / self.focal;
        // Fixed-point inversion of the distortion (each step shrinks the error by the
        // distortion's slope away from 1: a few for the pose2sim lenses, 40 steps leave
        // 1e-7 of the desk set's strong barrel at its corners).
        let mut n = target;
        for _ in 0..40 {
            n += target - self.distort(n);
        }
        n
    }

    /// A world point in the camera's frame (OpenCV axes).
    pub fn to_camera(&self, p: DVec3) -> DVec3 {
        self.rot * (p - self.pos)
    }

    /// A world point's pixel in a video of `video` pixels, `None` behind the camera.
    pub fn project(&self, video: DVec2, p: DVec3) -> Option<DVec2> {
        let c = self.to_camera(p);
        (c.z > 1e-6).then(|| {
            let (scale, pad) = self.letterbox(video);
            (self.distort(c.truncate() / c.z) * self.focal + self.centre) * scale + pad
        })
    }

    /// Pixels per unit of normalised image coordinates in a video of `video` pixels.
    pub fn pixels_per_unit(&self, video: DVec2) -> f64 {
        self.letterbox(video).0 * self.focal.x
    }
}

/// The point whose projections best meet the weighted rays (linear least squares over the
/// cameras' two projection equations each), `None` when they do not fix one.
pub fn triangulate(rays: &[(DVec2, f64, &Camera)]) -> Option<DVec3> {
    let (mut ata, mut atb) = (DMat3::ZERO, DVec3::ZERO);
    for &(n, w, cam) in rays {
        let t = -(cam.rot * cam.pos);
        let r = cam.rot.transpose(); // its columns are the rotation's rows
        for (row, coord, offset) in [(r.x_axis, n.x, t.x), (r.y_axis, n.y, t.y)] {
            // coord * (r3 . X + t3) = r_row . X + t_row
            let a = r.z_axis * coord - row;
            let b = offset - coord * t.z;
            ata += DMat3::from_cols(a * a.x, a * a.y, a * a.z) * w;
            atb += a * (b * w);
        }
    }
    (ata.determinant().abs() > 1e-12).then(|| ata.inverse() * atb)
}

/// The rotation, scale and translation taking `from` onto `to` at least squares (Umeyama's
/// similarity through Horn's quaternion: the top eigenvector of a symmetric 4×4 matrix), as
/// `from` mapped.
pub fn similarity_aligned(from: &[DVec3], to: &[DVec3]) -> Vec<DVec3> {
    let n = from.len().max(1) as f64;
    let (ca, cb) = (from.iter().sum::<DVec3>() / n, to.iter().sum::<DVec3>() / n);
    let mut s = [[0.0; 3]; 3];
    let mut norm = 0.0;
    for (a, b) in from.iter().zip(to) {
        let (a, b) = (*a - ca, *b - cb);
        norm += a.length_squared();
        for (i, ai) in a.to_array().into_iter().enumerate() {
            for (j, bj) in b.to_array().into_iter().enumerate() {
                s[i][j] += ai * bj;
            }
        }
    }
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = s;
    let k = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    let q = top_eigenvector(k);
    let rot = glam::DQuat::from_xyzw(q.y, q.z, q.w, q.x).normalize();
    let scale = from
        .iter()
        .zip(to)
        .map(|(a, b)| (rot * (*a - ca)).dot(*b - cb))
        .sum::<f64>()
        / norm.max(1e-12);
    from.iter().map(|a| rot * (*a - ca) * scale + cb).collect()
}

/// The eigenvector of the largest eigenvalue of a symmetric 4×4 matrix (cyclic Jacobi).
fn top_eigenvector(mut a: [[f64; 4]; 4]) -> DVec4 {
    let mut v = [[0.0; 4]; 4];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for _ in 0..50 {
        for p in 0..3 {
            for q in p + 1..4 {
                if a[p][q].abs() < 1e-15 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let sign = if theta >= 0.0 { 1.0 } else { -1.0 };
                let t = sign / (theta.abs() + (theta * theta + 1.0).sqrt());
                let (c, s) = (1.0 / (t * t + 1.0).sqrt(), t / (t * t + 1.0).sqrt());
                for row in a.iter_mut() {
                    let (x, y) = (row[p], row[q]);
                    row[p] = c * x - s * y;
                    row[q] = s * x + c * y;
                }
                let (head, tail) = a.split_at_mut(q);
                for (x, y) in head[p].iter_mut().zip(tail[0].iter_mut()) {
                    (*x, *y) = (c * *x - s * *y, s * *x + c * *y);
                }
                for row in v.iter_mut() {
                    let (x, y) = (row[p], row[q]);
                    row[p] = c * x - s * y;
                    row[q] = s * x + c * y;
                }
            }
        }
    }
    let best = (0..4)
        .max_by(|&i, &j| a[i][i].total_cmp(&a[j][j]))
        .unwrap_or(0);
    DVec4::new(v[0][best], v[1][best], v[2][best], v[3][best])
}
