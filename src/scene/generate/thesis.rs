//! Procedural versions of the thesis's two test scenes, written as glTF with
//! [`GltfBuilder`] (metres, +Y up):
//!
//! * [`open_box_figure_gltf`], the "Sahur" scene: an open box (floor, back, left and a
//!   red right wall; open at the top and the front) holding a detailed wooden figure with
//!   deep bark furrows, a carved face, limbs, fingers and a bat, next to a sphere, a cube,
//!   a cylinder and a cone. One large area light sits off to the front-left, above and
//!   outside the camera's view, tilted into the box.
//! * [`living_room_gltf`]: a closed room with a window in its right wall, lit only by one
//!   large area light outside the window; [`LIVING_ROOM_FURNITURE_PIECES`] furniture
//!   pieces leave regions (behind the couch, under the armchair and the cabinet) that
//!   only bounced light reaches. The floor, the rug and a painting carry procedural PNG
//!   textures.
//!
//! Both cameras are framed for a 16:9 image ([`SCENE_ASPECT`]); the light quads lie outside
//! their view frusta. Geometry is computed in `f64` and everything is deterministic (a
//! small integer hash replaces random numbers): the same call gives byte-identical text,
//! and `scenes/open_box_figure.gltf` / `scenes/living_room.gltf` are exactly this output.

use super::builder::GltfBuilder;
use glam::{DMat3, DQuat, DVec3, Mat4, Quat, Vec3};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Image aspect ratio (width / height) both scenes are framed for (rendered at 1280x720).
pub const SCENE_ASPECT: f32 = 16.0 / 9.0;

/// Name of the emissive quad's node (and mesh) in both scenes.
pub const LIGHT_NAME: &str = "light";

/// Name of the figure's mesh and node in the open box scene.
pub const FIGURE_NAME: &str = "figure";
/// The figure mesh has at least this many triangles (the generator gives 70,368).
pub const FIGURE_MIN_TRIANGLES: usize = 50_000;
/// Emitted radiance of the open box scene's light (linear RGB).
pub const OPEN_BOX_LIGHT_EMISSION: [f32; 3] = [14.0, 12.6, 10.6];
/// Interior of the open box: floor at y = 0, walls at x = ±1.2 and z = -1.2, height 1.5;
/// open at the top (y = 1.5) and the front (z = 0.8).
pub const OPEN_BOX_MIN: [f32; 3] = [-1.2, 0.0, -1.2];
/// See [`OPEN_BOX_MIN`].
pub const OPEN_BOX_MAX: [f32; 3] = [1.2, 1.5, 0.8];

/// Every furniture piece of the living room is one root node named with this prefix
/// (`furniture_couch`, ...) carrying the piece's placement; its parts are child mesh nodes
/// named `<piece>/<part>` (`furniture_couch/frame`), so loaded instances name their piece
/// before the first `/`.
pub const FURNITURE_PREFIX: &str = "furniture_";
/// Number of furniture pieces in the living room.
pub const LIVING_ROOM_FURNITURE_PIECES: usize = 26;
/// Emitted radiance of the living room's light, outside the window (linear RGB).
pub const LIVING_ROOM_LIGHT_EMISSION: [f32; 3] = [300.0, 280.0, 245.0];
/// Interior of the living room (floor, ceiling and the four walls lie on its faces).
pub const LIVING_ROOM_MIN: [f32; 3] = [-3.0, 0.0, -2.5];
/// See [`LIVING_ROOM_MIN`].
pub const LIVING_ROOM_MAX: [f32; 3] = [3.0, 2.7, 2.5];
/// The window opening in the right wall (x = 3): `[x, y_min, z_min]`..`[x, y_max, z_max]`.
pub const LIVING_ROOM_WINDOW_MIN: [f32; 3] = [3.0, 0.75, -1.9];
/// See [`LIVING_ROOM_WINDOW_MIN`].
pub const LIVING_ROOM_WINDOW_MAX: [f32; 3] = [3.0, 2.15, 0.1];
/// Depth of the window reveal (the wall's thickness), outward from x = 3.
const WALL_THICKNESS: f64 = 0.2;

// ---------------------------------------------------------------------------------------
// Deterministic noise
// ---------------------------------------------------------------------------------------

/// A 32-bit integer hash (lowbias32).
fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// Hash of a lattice point and a seed, mapped to [-1, 1].
fn lattice(ix: i64, iy: i64, seed: u32) -> f64 {
    let h = hash((ix as u32) ^ hash((iy as u32).wrapping_add(hash(seed))));
    h as f64 / u32::MAX as f64 * 2.0 - 1.0
}

/// Hash of an integer and a seed, mapped to [0, 1].
fn rand01(i: i64, seed: u32) -> f64 {
    0.5 + 0.5 * lattice(i, 0, seed)
}

/// Smoothly interpolated value noise in [-1, 1]; `period_x` > 0 makes it periodic in x.
fn value_noise(x: f64, y: f64, period_x: i64, seed: u32) -> f64 {
    let (fx, fy) = (x.floor(), y.floor());
    let (tx, ty) = (x - fx, y - fy);
    let (sx, sy) = (tx * tx * (3.0 - 2.0 * tx), ty * ty * (3.0 - 2.0 * ty));
    let wrap = |i: i64| {
        if period_x > 0 {
            i.rem_euclid(period_x)
        } else {
            i
        }
    };
    let (x0, y0) = (fx as i64, fy as i64);
    let v = |dx: i64, dy: i64| lattice(wrap(x0 + dx), y0 + dy, seed);
    let a = v(0, 0) + (v(1, 0) - v(0, 0)) * sx;
    let b = v(0, 1) + (v(1, 1) - v(0, 1)) * sx;
    a + (b - a) * sy
}

fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn gauss(x: f64, sigma: f64) -> f64 {
    (-(x / sigma) * (x / sigma)).exp()
}

// ---------------------------------------------------------------------------------------
// Mesh accumulation
// ---------------------------------------------------------------------------------------

/// Which way the front faces of a generated surface point.
#[derive(Clone, Copy)]
enum Facing {
    /// A closed surface: front faces point out of the enclosed volume.
    Outward,
    /// An open surface: front faces point (on average) along this direction.
    Toward(DVec3),
}

/// One mesh under construction: per-vertex positions, normals and UVs, triangle indices.
#[derive(Default)]
struct MeshData {
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    uvs: Vec<[f64; 2]>,
    indices: Vec<u32>,
}

impl MeshData {
    /// A flat quad, CCW front face as given (two triangles).
    fn quad(&mut self, c: [DVec3; 4], uv: [[f64; 2]; 4]) {
        let n = (c[2] - c[0]).cross(c[3] - c[1]).normalize_or_zero();
        let base = self.positions.len() as u32;
        for (p, t) in c.into_iter().zip(uv) {
            self.positions.push(p);
            self.normals.push(n);
            self.uvs.push(t);
        }
        self.indices.extend([0, 1, 2, 0, 2, 3].map(|i| base + i));
    }

    /// A flat quad turned so that its front face points along `dir`, UVs 0..1.
    fn quad_facing(&mut self, c: [DVec3; 4], dir: DVec3) {
        let flipped = (c[2] - c[0]).cross(c[3] - c[1]).dot(dir) < 0.0;
        let c = if flipped { [c[0], c[3], c[2], c[1]] } else { c };
        self.quad(c, [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
    }

    /// An axis-aligned box with outward faces; UVs are the face's coordinates in metres.
    fn cuboid(&mut self, min: DVec3, max: DVec3) {
        self.cuboid_faces(min, max, [true; 6]);
    }

    /// Like [`MeshData::cuboid`], keeping only the faces flagged in `keep`
    /// (order: -x, +x, -y, +y, -z, +z).
    fn cuboid_faces(&mut self, min: DVec3, max: DVec3, keep: [bool; 6]) {
        for axis in 0..3 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for (k, side) in [(0usize, -1.0f64), (1, 1.0)] {
                if !keep[2 * axis + k] {
                    continue;
                }
                let at = |a: bool, b: bool| {
                    let mut p = DVec3::ZERO;
                    p[axis] = if k == 1 { max[axis] } else { min[axis] };
                    p[u] = if a { max[u] } else { min[u] };
                    p[v] = if b { max[v] } else { min[v] };
                    p
                };
                let mut c = [
                    at(false, false),
                    at(true, false),
                    at(true, true),
                    at(false, true),
                ];
                let mut dir = DVec3::ZERO;
                dir[axis] = side;
                if (c[2] - c[0]).cross(c[3] - c[1]).dot(dir) < 0.0 {
                    c = [c[0], c[3], c[2], c[1]];
                }
                let uv = c.map(|p| [p[u], p[v]]);
                self.quad(c, uv);
            }
        }
    }

    /// A box rotated by `yaw` about its vertical centre line.
    fn cuboid_yaw(&mut self, center: DVec3, half: DVec3, yaw: f64) {
        let start = self.positions.len();
        self.cuboid(-half, half);
        let rot = DQuat::from_rotation_y(yaw);
        for i in start..self.positions.len() {
            self.positions[i] = center + rot * self.positions[i];
            self.normals[i] = rot * self.normals[i];
        }
    }

    /// A smooth grid surface with `nu` x `nv` cells; `f(i, j)` gives the vertex for
    /// `i` in `0..=nu` (or `0..nu` with `wrap_u`, where column `nu` is column 0) and
    /// `j` in `0..=nv`. Zero-area triangles (at poles) are skipped; normals are the
    /// area-weighted averages of the adjacent faces.
    fn surface(
        &mut self,
        nu: usize,
        nv: usize,
        wrap_u: bool,
        facing: Facing,
        f: impl Fn(usize, usize) -> DVec3,
    ) {
        let cols = if wrap_u { nu } else { nu + 1 };
        let base = self.positions.len();
        for j in 0..=nv {
            for i in 0..cols {
                self.positions.push(f(i, j));
                self.uvs.push([i as f64 / nu as f64, j as f64 / nv as f64]);
            }
        }
        let id = |i: usize, j: usize| base + j * cols + if wrap_u { i % nu } else { i };
        let mut tris: Vec<[usize; 3]> = Vec::with_capacity(2 * nu * nv);
        for j in 0..nv {
            for i in 0..nu {
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                for t in [[a, b, c], [a, c, d]] {
                    let [p, q, r] = t.map(|k| self.positions[k]);
                    if (q - p).cross(r - p).length_squared() > 1e-18 {
                        tris.push(t);
                    }
                }
            }
        }
        let flip = match facing {
            Facing::Outward => {
                let n = (self.positions.len() - base) as f64;
                let centre = self.positions[base..].iter().sum::<DVec3>() / n;
                let volume: f64 = tris
                    .iter()
                    .map(|t| {
                        let [p, q, r] = t.map(|k| self.positions[k] - centre);
                        p.dot(q.cross(r))
                    })
                    .sum();
                volume < 0.0
            }
            Facing::Toward(dir) => {
                let sum: DVec3 = tris
                    .iter()
                    .map(|t| {
                        let [p, q, r] = t.map(|k| self.positions[k]);
                        (q - p).cross(r - p)
                    })
                    .sum();
                sum.dot(dir) < 0.0
            }
        };
        let mut normals = vec![DVec3::ZERO; self.positions.len() - base];
        for t in &mut tris {
            if flip {
                t.swap(1, 2);
            }
            let [p, q, r] = t.map(|k| self.positions[k]);
            let n = (q - p).cross(r - p);
            for &k in t.iter() {
                normals[k - base] += n;
            }
            self.indices.extend(t.map(|k| k as u32));
        }
        self.normals
            .extend(normals.into_iter().map(|n| n.normalize_or_zero()));
    }

    /// A closed tube swept along `path` (at least 2 points) with parallel-transported
    /// frames; `radius(j, theta)` is the radius at path point `j`; the ends close with
    /// rounded caps of `cap` path points each (radius shrinking to 0 on a quarter circle).
    fn tube(&mut self, path: &[DVec3], nu: usize, cap: usize, radius: impl Fn(usize, f64) -> f64) {
        let n = path.len();
        let tangent = |j: usize| (path[(j + 1).min(n - 1)] - path[j.saturating_sub(1)]).normalize();
        let mut frames = Vec::with_capacity(n);
        let t0 = tangent(0);
        let helper = if t0.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
        let mut normal = (helper - t0 * helper.dot(t0)).normalize();
        for j in 0..n {
            let t = tangent(j);
            normal = (normal - t * normal.dot(t)).normalize();
            frames.push((normal, t.cross(normal)));
        }
        let end_scale = |j: usize| {
            let k = j.min(n - 1 - j);
            if cap == 0 || k >= cap {
                1.0
            } else {
                let a = k as f64 / cap as f64;
                (1.0 - (1.0 - a) * (1.0 - a)).sqrt()
            }
        };
        self.surface(nu, n - 1, true, Facing::Outward, |i, j| {
            let theta = TAU * i as f64 / nu as f64;
            let (nrm, bin) = frames[j];
            path[j] + (nrm * theta.cos() + bin * theta.sin()) * radius(j, theta) * end_scale(j)
        });
    }

    /// An ellipsoid (`nu` around, `nv` pole to pole) transformed by `rot` about `center`,
    /// with optional radial displacement `disp(theta, phi)` (phi from -pi/2 to pi/2).
    fn ellipsoid(
        &mut self,
        center: DVec3,
        radii: DVec3,
        rot: DQuat,
        nu: usize,
        nv: usize,
        disp: impl Fn(f64, f64) -> f64,
    ) {
        self.surface(nu, nv, true, Facing::Outward, |i, j| {
            let theta = TAU * i as f64 / nu as f64;
            let phi = -FRAC_PI_2 + PI * j as f64 / nv as f64;
            let dir = DVec3::new(phi.cos() * theta.cos(), phi.sin(), phi.cos() * theta.sin());
            let p = dir * radii * (1.0 + disp(theta, phi));
            center + rot * p
        });
    }

    /// A closed cylinder or cone frustum around the vertical axis through `base`
    /// (bottom radius `r0`, top radius `r1`), flat caps, smooth sides.
    fn frustum(&mut self, base: DVec3, r0: f64, r1: f64, height: f64, nu: usize) {
        // Rows: bottom centre, bottom rim (twice, for a crease), top rim (twice), top centre.
        let rows = [(0.0, 0.0), (0.0, r0), (height, r1), (height, 0.0)];
        for (a, b) in [(0, 1), (1, 2), (2, 3)] {
            let (ya, ra) = rows[a];
            let (yb, rb) = rows[b];
            if ra == 0.0 && rb == 0.0 {
                continue; // a cone's (empty) top cap
            }
            self.surface(nu, 1, true, Facing::Toward(DVec3::ZERO), |i, j| {
                let theta = TAU * i as f64 / nu as f64;
                let (y, r) = if j == 0 { (ya, ra) } else { (yb, rb) };
                base + DVec3::new(r * theta.cos(), y, -r * theta.sin())
            });
        }
        // Parametrised with theta running clockwise seen from above and rows going up,
        // the side faces point outward, the bottom down and the top up.
    }

    /// Adds the mesh (with UVs when `textured`) and returns its glTF index.
    fn emit(&self, b: &mut GltfBuilder, name: &str, material: usize, textured: bool) -> usize {
        let positions: Vec<[f32; 3]> = self
            .positions
            .iter()
            .map(|p| p.as_vec3().to_array())
            .collect();
        let normals: Vec<[f32; 3]> = self
            .normals
            .iter()
            .map(|n| n.as_vec3().to_array())
            .collect();
        if textured {
            let uvs: Vec<[f32; 2]> = self
                .uvs
                .iter()
                .map(|t| [t[0] as f32, t[1] as f32])
                .collect();
            b.mesh_with_uvs(
                name,
                &positions,
                Some(&normals),
                &uvs,
                &self.indices,
                material,
            )
        } else {
            b.mesh(name, &positions, Some(&normals), &self.indices, material)
        }
    }
}

/// Adds `mesh` as a root node named `name`.
fn place(b: &mut GltfBuilder, name: &str, mesh: &MeshData, material: usize) -> usize {
    let m = mesh.emit(b, name, material, false);
    b.node(name, m, [0.0; 3])
}

/// Quadratic Bézier through `p0`, control `c`, `p1`, sampled at `n + 1` points.
fn bezier(p0: DVec3, c: DVec3, p1: DVec3, n: usize) -> Vec<DVec3> {
    (0..=n)
        .map(|j| {
            let t = j as f64 / n as f64;
            p0 * (1.0 - t) * (1.0 - t) + c * 2.0 * t * (1.0 - t) + p1 * t * t
        })
        .collect()
}

/// Emissive quad, centred at `center`, `size` = (width, height), front face along `normal`.
fn light_quad(center: DVec3, normal: DVec3, size: (f64, f64)) -> [DVec3; 4] {
    let n = normal.normalize();
    let right = DVec3::Y.cross(n).normalize();
    let up = n.cross(right);
    let (w, h) = (0.5 * size.0 * right, 0.5 * size.1 * up);
    // right x up = n: (-w-h, +w-h, +w+h, -w+h) is counter-clockwise seen from the front.
    [
        center - w - h,
        center + w - h,
        center + w + h,
        center - w + h,
    ]
}

// ---------------------------------------------------------------------------------------
// The open box with the figure
// ---------------------------------------------------------------------------------------

/// Body of the figure: a rounded log, axis at (x, z) = (0, FIG_Z) on the floor plan.
const FIG_X: f64 = 0.05;
const FIG_Z: f64 = -0.35;
const BODY_BOTTOM: f64 = 0.40;
const BODY_TOP: f64 = 1.28;
const BODY_R: f64 = 0.165;
/// Depth scale of the body's cross-section (an ellipse, narrower front to back).
const BODY_DEPTH: f64 = 0.9;
/// Height of the face's centre (eyes a little above, mouth below).
const FACE_Y: f64 = 1.0;

/// Face-relative coordinates of a body point: horizontal arc length `s` from the face's
/// centre line (positive toward +x) and height `y`.
fn face_coords(theta: f64, y: f64) -> (f64, f64) {
    (BODY_R * (FRAC_PI_2 - theta), y)
}

/// Radial displacement of the body surface: bark plates separated by sharp furrows,
/// horizontal cracks and fine grain, smoothed over a carved face (eye sockets, nose,
/// brows and a smiling mouth).
fn body_displacement(theta: f64, y: f64) -> f64 {
    const PLATES: i64 = 15;
    // Noise in x = theta / 2pi * period is periodic around the body for an integer period.
    let around = |period: i64| theta / TAU * period as f64;
    let u = around(PLATES);
    let warp = 0.45 * value_noise(around(8), y * 5.0, 8, 11)
        + 0.15 * value_noise(around(24), y * 14.0, 24, 12);
    let f = (u + warp).rem_euclid(1.0);
    // Rounded plates, V-shaped furrows at f = 0.
    let plate = (PI * f).sin().max(0.0).powf(0.45);
    let plate_id = ((u + warp).floor() as i64).rem_euclid(PLATES);
    let furrow_depth = 0.027 * (0.8 + 0.4 * rand01(plate_id, 13));
    let mut d = furrow_depth * (plate - 1.0);
    // Horizontal cracks across the plates.
    let cy = y * 7.0 + 0.6 * value_noise(u, y * 3.0, PLATES, 14);
    let crack = gauss((cy.rem_euclid(1.0)) - 0.5, 0.05) * smoothstep(0.2, 0.6, plate);
    d -= 0.012 * crack * (0.5 + 0.5 * value_noise(around(30), y * 7.0, 30, 15));
    // Fine grain along the plates.
    d += 0.0025 * value_noise(around(90), y * 60.0, 90, 16);

    // The face: bark smoothed away in an oval, then carved features.
    let (s, fy) = face_coords(theta, y);
    let mask = (-(s / 0.095).powi(2) - ((fy - FACE_Y) / 0.16).powi(2)).exp();
    let mut face = 0.0;
    for side in [-1.0, 1.0] {
        let (ex, ey) = (s - side * 0.055, fy - (FACE_Y + 0.06));
        face -= 0.03 * (-(ex / 0.027).powi(2) - (ey / 0.03).powi(2)).exp();
        let (bx, by) = (s - side * 0.058, fy - (FACE_Y + 0.108));
        face += 0.012 * (-(bx / 0.035).powi(2) - (by / 0.011).powi(2)).exp();
    }
    face += 0.04 * (-(s / 0.017).powi(2) - ((fy - FACE_Y + 0.005) / 0.04).powi(2)).exp();
    let smile = fy - (FACE_Y - 0.085 + 12.0 * s * s);
    face -= 0.014 * gauss(smile, 0.008) * smoothstep(0.085, 0.06, s.abs());
    let top = smoothstep(BODY_TOP - 0.02, BODY_TOP - 0.1, y)
        * smoothstep(BODY_BOTTOM + 0.01, BODY_BOTTOM + 0.08, y);
    (d * (1.0 - 0.9 * mask) + face * (0.4 + 0.6 * mask)) * top
}

/// Body surface point at angle `theta` (0 = +x, pi/2 = +z, toward the camera), height `y`
/// and base radius `r`, displaced by `d`.
fn body_point(theta: f64, y: f64, r: f64, d: f64) -> DVec3 {
    let rr = (r + d).max(0.0);
    DVec3::new(
        FIG_X + rr * theta.cos(),
        y,
        FIG_Z + BODY_DEPTH * rr * theta.sin(),
    )
}

/// Builds the figure (one mesh) and its eyes/pupils; returns (figure, eyes, pupils).
fn figure_meshes() -> (MeshData, MeshData, MeshData) {
    let mut fig = MeshData::default();

    // Body: rows of (y, base radius) on a log with rounded ends; the bark covers the sides.
    const NU: usize = 160;
    const CAP_ROWS: usize = 10;
    const SIDE_ROWS: usize = 120;
    let cap = 0.06;
    let mut rows = Vec::new();
    for k in 0..=CAP_ROWS {
        let a = -FRAC_PI_2 + FRAC_PI_2 * k as f64 / CAP_ROWS as f64;
        let r = if k == 0 { 0.0 } else { BODY_R * a.cos() };
        rows.push((BODY_BOTTOM + cap * (1.0 + a.sin()), r));
    }
    for k in 1..SIDE_ROWS {
        let t = k as f64 / SIDE_ROWS as f64;
        let y = BODY_BOTTOM + cap + t * (BODY_TOP - BODY_BOTTOM - 2.0 * cap);
        // A slight barrel shape.
        rows.push((y, BODY_R * (1.0 + 0.05 * (PI * t).sin())));
    }
    for k in 0..=CAP_ROWS {
        let a = FRAC_PI_2 * k as f64 / CAP_ROWS as f64;
        let r = if k == CAP_ROWS { 0.0 } else { BODY_R * a.cos() };
        rows.push((BODY_TOP - cap + cap * a.sin(), r));
    }
    fig.surface(NU, rows.len() - 1, true, Facing::Outward, |i, j| {
        let theta = TAU * i as f64 / NU as f64;
        let (y, r) = rows[j];
        let d = if r > 0.0 {
            body_displacement(theta, y)
        } else {
            0.0
        };
        body_point(theta, y, r, d)
    });

    // Limbs: thin tubes with a few grooves of bark.
    let limb = |fig: &mut MeshData, path: Vec<DVec3>, r0: f64, r1: f64, seed: u32| {
        let n = path.len();
        fig.tube(&path, 28, 4, |j, theta| {
            let t = j as f64 / (n - 1) as f64;
            let r = r0 + (r1 - r0) * t;
            let groove = (theta * 5.0 + 2.0 * value_noise(t * 6.0, 0.0, 0, seed)).sin();
            let x = theta / TAU * 4.0;
            r * (1.0 - 0.12 * groove.abs().powf(6.0) + 0.03 * value_noise(x, t * 20.0, 4, seed + 1))
        });
    };
    let shoulder_y = 1.02;
    // The figure's right arm (screen left, -x) hangs down; the left arm (screen right,
    // +x) is bent forward, holding the bat.
    let hang_hand = DVec3::new(FIG_X - 0.33, 0.62, FIG_Z + 0.05);
    limb(
        &mut fig,
        bezier(
            DVec3::new(FIG_X - 0.14, shoulder_y, FIG_Z),
            DVec3::new(FIG_X - 0.36, 0.92, FIG_Z - 0.06),
            hang_hand,
            60,
        ),
        0.032,
        0.026,
        20,
    );
    let grip_hand = DVec3::new(FIG_X + 0.34, 0.72, FIG_Z + 0.16);
    limb(
        &mut fig,
        bezier(
            DVec3::new(FIG_X + 0.14, shoulder_y, FIG_Z),
            DVec3::new(FIG_X + 0.38, 0.80, FIG_Z - 0.05),
            grip_hand,
            60,
        ),
        0.032,
        0.026,
        22,
    );
    // Legs and feet.
    for (side, seed) in [(-1.0, 30), (1.0, 32)] {
        let x = FIG_X + side * 0.075;
        limb(
            &mut fig,
            bezier(
                DVec3::new(x, BODY_BOTTOM + 0.06, FIG_Z),
                DVec3::new(x + side * 0.03, 0.24, FIG_Z + 0.05),
                DVec3::new(x + side * 0.02, 0.06, FIG_Z),
                50,
            ),
            0.036,
            0.03,
            seed,
        );
        fig.ellipsoid(
            DVec3::new(x + side * 0.025, 0.035, FIG_Z + 0.05),
            DVec3::new(0.05, 0.035, 0.095),
            DQuat::from_rotation_y(-side * 0.2),
            32,
            20,
            |theta, phi| {
                0.04 * (theta * 6.0).sin().abs() * phi.cos().powi(4) * smoothstep(0.3, -0.1, phi)
            },
        );
    }
    // Hands: a palm and five curled fingers each.
    for (hand, dir, seed) in [
        (hang_hand, DVec3::new(-0.1, -1.0, 0.15), 40u32),
        (grip_hand, DVec3::new(0.3, -0.2, 1.0), 50),
    ] {
        let dir = dir.normalize();
        let side = dir.cross(DVec3::Y).normalize_or(DVec3::X);
        let up = side.cross(dir).normalize();
        let palm = hand + dir * 0.035;
        let rot = DQuat::from_mat3(&DMat3::from_cols(side, up, side.cross(up)));
        fig.ellipsoid(
            palm,
            DVec3::new(0.042, 0.022, 0.045),
            rot,
            24,
            16,
            |_, _| 0.0,
        );
        for f in 0..5 {
            let (across, len, base_fwd) = if f == 4 {
                (-0.04, 0.05, 0.0)
            } else {
                (
                    -0.027 + 0.018 * f as f64,
                    0.06 - 0.006 * (f as f64 - 1.5).abs(),
                    0.03,
                )
            };
            let b0 = palm + side * across + dir * base_fwd;
            let curl = 0.6 + 0.3 * rand01(f, seed);
            let mid = b0 + dir * len * 0.7 - up * len * 0.3 * curl
                + side * (if f == 4 { -0.015 } else { 0.0 });
            let tip = b0 + dir * len * 0.55 - up * len * curl;
            fig.tube(&bezier(b0, mid, tip, 16), 12, 3, |_, _| 0.0105);
        }
    }
    // The bat, held in the bent arm's hand, leaning up and out.
    let bat_dir = DVec3::new(0.42, 0.88, 0.2).normalize();
    let bat_start = grip_hand + DVec3::new(0.0, -0.02, 0.05) - bat_dir * 0.12;
    let bat_len = 0.78;
    let bat: Vec<DVec3> = (0..=80)
        .map(|j| bat_start + bat_dir * bat_len * j as f64 / 80.0)
        .collect();
    fig.tube(&bat, 40, 5, |j, _| {
        let t = j as f64 / 80.0;
        let knob = 0.012 * gauss(t - 0.02, 0.025);
        0.018 + knob + 0.03 * smoothstep(0.3, 0.75, t)
    });

    // Eyes: white balls in the sockets, dark pupils in front.
    let mut eyes = MeshData::default();
    let mut pupils = MeshData::default();
    for side in [-1.0, 1.0] {
        let theta = FRAC_PI_2 - side * 0.055 / BODY_R;
        let y = FACE_Y + 0.06;
        let outward = DVec3::new(theta.cos(), 0.0, BODY_DEPTH * theta.sin()).normalize();
        let c = body_point(theta, y, BODY_R * 1.05, -0.02);
        eyes.ellipsoid(c, DVec3::splat(0.024), DQuat::IDENTITY, 24, 16, |_, _| 0.0);
        pupils.ellipsoid(
            c + outward * 0.02,
            DVec3::splat(0.0095),
            DQuat::IDENTITY,
            16,
            10,
            |_, _| 0.0,
        );
    }
    (fig, eyes, pupils)
}

/// The "Sahur" open box scene as glTF JSON text: floor, back and left walls (light grey)
/// and a red right wall (+x, on screen right), open at the top and the front; a wooden
/// figure (one mesh, at least [`FIGURE_MIN_TRIANGLES`] triangles, smooth normals) with
/// bark furrows, a carved face, limbs, fingers and a bat; a blue sphere, a yellow cube, a
/// green cylinder and an orange cone; one 1.4 m square light (Le =
/// [`OPEN_BOX_LIGHT_EMISSION`]) above the front-left, outside the camera's view, tilted
/// into the box; a camera in front of the opening, framed for 16:9.
pub fn open_box_figure_gltf() -> String {
    let mut b = GltfBuilder::new();
    let white = b.material("wall_white", [0.72, 0.72, 0.7], [0.0; 3], false);
    let red = b.material("wall_red", [0.75, 0.06, 0.045], [0.0; 3], false);
    let wood = b.material("figure_wood", [0.62, 0.47, 0.32], [0.0; 3], false);
    let eye_white = b.material("eye_white", [0.85, 0.85, 0.82], [0.0; 3], false);
    let pupil = b.material("eye_pupil", [0.03, 0.03, 0.03], [0.0; 3], false);
    let blue = b.material("blue", [0.1, 0.22, 0.7], [0.0; 3], false);
    let yellow = b.material("yellow", [0.8, 0.65, 0.1], [0.0; 3], false);
    let green = b.material("green", [0.12, 0.5, 0.15], [0.0; 3], false);
    let orange = b.material("orange", [0.85, 0.35, 0.08], [0.0; 3], false);
    let light = b.material("light", [0.78, 0.78, 0.78], OPEN_BOX_LIGHT_EMISSION, false);

    let (lo, hi) = (
        DVec3::from(Vec3::from(OPEN_BOX_MIN)),
        DVec3::from(Vec3::from(OPEN_BOX_MAX)),
    );
    let v = DVec3::new;
    for (name, corners, dir, material) in [
        (
            "floor",
            [
                v(lo.x, 0.0, lo.z),
                v(hi.x, 0.0, lo.z),
                v(hi.x, 0.0, hi.z),
                v(lo.x, 0.0, hi.z),
            ],
            DVec3::Y,
            white,
        ),
        (
            "back_wall",
            [
                v(lo.x, 0.0, lo.z),
                v(hi.x, 0.0, lo.z),
                v(hi.x, hi.y, lo.z),
                v(lo.x, hi.y, lo.z),
            ],
            DVec3::Z,
            white,
        ),
        (
            "left_wall",
            [
                v(lo.x, 0.0, lo.z),
                v(lo.x, 0.0, hi.z),
                v(lo.x, hi.y, hi.z),
                v(lo.x, hi.y, lo.z),
            ],
            DVec3::X,
            white,
        ),
        (
            "right_wall_red",
            [
                v(hi.x, 0.0, lo.z),
                v(hi.x, 0.0, hi.z),
                v(hi.x, hi.y, hi.z),
                v(hi.x, hi.y, lo.z),
            ],
            DVec3::NEG_X,
            red,
        ),
    ] {
        let mut m = MeshData::default();
        m.quad_facing(corners, dir);
        place(&mut b, name, &m, material);
    }

    let (fig, eyes, pupils) = figure_meshes();
    place(&mut b, FIGURE_NAME, &fig, wood);
    place(&mut b, "figure_eyes", &eyes, eye_white);
    place(&mut b, "figure_pupils", &pupils, pupil);

    // Basic geometric objects.
    let mut sphere = MeshData::default();
    sphere.ellipsoid(
        v(-0.62, 0.2, 0.12),
        DVec3::splat(0.2),
        DQuat::IDENTITY,
        64,
        32,
        |_, _| 0.0,
    );
    place(&mut b, "sphere", &sphere, blue);
    let mut cube = MeshData::default();
    cube.cuboid_yaw(v(0.66, 0.16, 0.2), DVec3::splat(0.16), 0.45);
    place(&mut b, "cube", &cube, yellow);
    let mut cylinder = MeshData::default();
    cylinder.frustum(v(-0.72, 0.0, -0.72), 0.14, 0.14, 0.5, 48);
    place(&mut b, "cylinder", &cylinder, green);
    let mut cone = MeshData::default();
    cone.frustum(v(0.72, 0.0, -0.7), 0.17, 0.0, 0.42, 48);
    place(&mut b, "cone", &cone, orange);

    // One large area light above the front-left, aimed into the box.
    let center = v(-2.3, 2.4, 2.1);
    let aim = v(0.15, 0.45, -0.5);
    let mut l = MeshData::default();
    l.quad(
        light_quad(center, aim - center, (1.4, 1.4)),
        [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
    );
    place(&mut b, LIGHT_NAME, &l, light);

    b.camera(
        "camera",
        [0.0, 0.95, 3.25],
        [0.0, 0.62, -0.35],
        [0.0, 1.0, 0.0],
        38f32.to_radians(),
    );
    b.to_json_string()
}

// ---------------------------------------------------------------------------------------
// Textures
// ---------------------------------------------------------------------------------------

fn srgb8(c: DVec3) -> [u8; 4] {
    let q = |x: f64| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    [q(c.x), q(c.y), q(c.z), 255]
}

/// Wood planks (sRGB): 8 planks across v, joints staggered along u, grain and gaps.
fn wood_planks_texture(size: u32) -> Vec<u8> {
    let mut out = Vec::with_capacity((size * size * 4) as usize);
    let planks = 8u32;
    let plank_h = size / planks;
    for y in 0..size {
        let row = y / plank_h;
        let ry = (y % plank_h) as f64 / plank_h as f64;
        for x in 0..size {
            let offset = (rand01(row as i64, 101) * size as f64) as u32;
            let xs = (x + offset) % size;
            let segment = if xs < size / 2 { 0 } else { 1 };
            let id = (row * 2 + segment) as i64;
            let tone = 0.8 + 0.4 * rand01(id, 102);
            let base = DVec3::new(0.60, 0.40, 0.24) * tone;
            let u = x as f64 / size as f64;
            let grain_phase =
                ry * 9.0 + 1.8 * value_noise(u * 6.0, ry * 2.0 + id as f64 * 3.0, 6, 103);
            let grain = 0.5 + 0.5 * (grain_phase * TAU).sin();
            let mut c = base * (0.86 + 0.14 * grain.powi(3));
            c *= 1.0 + 0.06 * value_noise(u * 40.0, ry * 4.0 + id as f64 * 7.0, 40, 104);
            let gap = y % plank_h == 0 || xs.is_multiple_of(size / 2);
            if gap {
                c *= 0.45;
            }
            out.extend(srgb8(c));
        }
    }
    out
}

/// A rug (sRGB): dark red border, cream field with a blue and red diamond lattice.
fn rug_texture(size: u32) -> Vec<u8> {
    let mut out = Vec::with_capacity((size * size * 4) as usize);
    let (red, cream, blue, dark) = (
        DVec3::new(0.55, 0.1, 0.08),
        DVec3::new(0.85, 0.78, 0.62),
        DVec3::new(0.12, 0.2, 0.45),
        DVec3::new(0.2, 0.06, 0.05),
    );
    for y in 0..size {
        for x in 0..size {
            let (u, v) = (
                (x as f64 + 0.5) / size as f64,
                (y as f64 + 0.5) / size as f64,
            );
            let edge = u.min(v).min(1.0 - u).min(1.0 - v);
            let c = if edge < 0.03 {
                dark
            } else if edge < 0.1 {
                if ((u + v) * 40.0).floor() as i64 % 2 == 0 {
                    red
                } else {
                    red * 0.7
                }
            } else {
                let (a, b) = ((u - 0.5) * 6.0, (v - 0.5) * 6.0);
                let d = (a.rem_euclid(1.0) - 0.5).abs() + (b.rem_euclid(1.0) - 0.5).abs();
                if d < 0.18 {
                    red
                } else if (d - 0.35).abs() < 0.05 {
                    blue
                } else {
                    cream
                }
            };
            out.extend(srgb8(
                c * (0.93 + 0.07 * value_noise(u * 64.0, v * 64.0, 0, 201)),
            ));
        }
    }
    out
}

/// A painting (sRGB): evening sky, sun, layered hills.
fn painting_texture(w: u32, h: u32) -> Vec<u8> {
    let mut out = Vec::with_capacity((w * h * 4) as usize);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = ((x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64);
            // v = 0 is the top row.
            let sky = DVec3::new(0.95, 0.55, 0.25)
                .lerp(DVec3::new(0.25, 0.3, 0.6), (1.0 - v / 0.7).clamp(0.0, 1.0));
            let mut c = sky;
            if ((u - 0.68).powi(2) + (v - 0.42).powi(2) * 0.6).sqrt() < 0.09 {
                c = DVec3::new(1.0, 0.9, 0.6);
            }
            for (k, colour) in [
                DVec3::new(0.3, 0.35, 0.45),
                DVec3::new(0.18, 0.32, 0.2),
                DVec3::new(0.1, 0.2, 0.1),
            ]
            .into_iter()
            .enumerate()
            {
                let k = k as f64;
                let ridge = 0.5
                    + 0.1 * k
                    + 0.06 * (u * (7.0 + 3.0 * k) + k).sin()
                    + 0.03 * value_noise(u * 12.0, k, 0, 300);
                if v > ridge {
                    c = colour;
                }
            }
            out.extend(srgb8(c));
        }
    }
    out
}

// ---------------------------------------------------------------------------------------
// The living room
// ---------------------------------------------------------------------------------------

/// Materials of the living room, by role.
struct RoomMaterials {
    wall: usize,
    ceiling: usize,
    wood_light: usize,
    wood_dark: usize,
    fabric_couch: usize,
    fabric_cushion: usize,
    fabric_chair: usize,
    metal: usize,
    black: usize,
    screen: usize,
    cream: usize,
    pot: usize,
    leaves: usize,
    book: [usize; 4],
    curtain: usize,
    frame: usize,
    picture: usize,
}

/// Adds a furniture piece: a group node `furniture_<name>` at `pos`, rotated by `yaw`
/// about +Y, with one child mesh node per part.
fn furniture(
    b: &mut GltfBuilder,
    name: &str,
    pos: DVec3,
    yaw: f64,
    parts: Vec<(&str, MeshData, usize, bool)>,
) {
    let piece = format!("{FURNITURE_PREFIX}{name}");
    let matrix = Mat4::from_rotation_translation(Quat::from_rotation_y(yaw as f32), pos.as_vec3());
    let group = b.group(&piece, matrix.to_cols_array());
    for (part, mesh, material, textured) in parts {
        let part_name = format!("{piece}/{part}");
        let m = mesh.emit(b, &part_name, material, textured);
        let node = b.node(&part_name, m, [0.0; 3]);
        b.add_child(group, node);
    }
}

/// A table: top (`size` = width x, depth z, height to the top surface) and four legs.
fn table(size: DVec3, top_thickness: f64, leg: f64) -> MeshData {
    let mut m = MeshData::default();
    let (hx, hz) = (size.x / 2.0, size.z / 2.0);
    m.cuboid(
        DVec3::new(-hx, size.y - top_thickness, -hz),
        DVec3::new(hx, size.y, hz),
    );
    for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        let c = DVec3::new(sx * (hx - 1.5 * leg), 0.0, sz * (hz - 1.5 * leg));
        m.cuboid(
            c - DVec3::new(leg / 2.0, 0.0, leg / 2.0),
            c + DVec3::new(leg / 2.0, size.y - top_thickness, leg / 2.0),
        );
    }
    m
}

/// A chair facing -z (seat, four legs, backrest at +z).
fn chair() -> MeshData {
    let mut m = table(DVec3::new(0.44, 0.46, 0.44), 0.04, 0.04);
    m.cuboid(DVec3::new(-0.22, 0.46, 0.18), DVec3::new(0.22, 0.95, 0.22));
    for x in [-0.1, 0.0, 0.1] {
        m.cuboid(
            DVec3::new(x - 0.015, 0.46, 0.185),
            DVec3::new(x + 0.015, 0.9, 0.215),
        );
    }
    m
}

/// A leafy plant's foliage: `n` flattened ellipsoid leaves (up to `length` long)
/// fanning out from `base`.
fn foliage(base: DVec3, n: usize, length: f64, seed: u32) -> MeshData {
    let mut m = MeshData::default();
    for k in 0..n {
        let yaw = TAU * (k as f64 / n as f64 + 0.3 * rand01(k as i64, seed));
        let tilt = 0.2 + 0.55 * rand01(k as i64, seed + 1);
        let half = 0.5 * length * (0.7 + 0.3 * rand01(k as i64, seed + 2));
        let rot = DQuat::from_rotation_y(yaw) * DQuat::from_rotation_x(tilt);
        let centre = base + rot * DVec3::new(0.0, half, 0.0);
        m.ellipsoid(
            centre,
            DVec3::new(0.045, half, 0.012),
            rot,
            12,
            10,
            |_, _| 0.0,
        );
    }
    m
}

/// A pleated curtain hanging in the plane x = `x` over `z0..z1`, facing -x (into the room).
fn curtain(x: f64, z0: f64, z1: f64, y0: f64, y1: f64) -> MeshData {
    let mut m = MeshData::default();
    let (nu, nv) = (64, 6);
    m.surface(nu, nv, false, Facing::Toward(DVec3::NEG_X), |i, j| {
        let t = i as f64 / nu as f64;
        let z = z0 + (z1 - z0) * t;
        let y = y0 + (y1 - y0) * j as f64 / nv as f64;
        let pleat = 0.035 * (t * TAU * 5.0).sin() * (0.6 + 0.4 * (j as f64 / nv as f64));
        DVec3::new(x - 0.05 + pleat, y, z)
    });
    m
}

/// The living room as glTF JSON text: a 6 m x 5 m x 2.7 m room (floor, ceiling, four walls
/// facing inward) with a 2 m x 1.4 m window in the right wall (+x; the wall is built from
/// four quads around the hole, with a reveal and a cross-shaped frame), one 2 m x 1.5 m
/// light 5.5 m outside, facing the window (Le = [`LIVING_ROOM_LIGHT_EMISSION`]), and
/// [`LIVING_ROOM_FURNITURE_PIECES`] furniture pieces (see [`FURNITURE_PREFIX`]). The floor
/// (wood planks), the rug and the painting have PNG base colour textures with `TEXCOORD_0`;
/// everything else is untextured. The camera stands in the front-right corner looking
/// toward the back-left, framed for 16:9; the window and the light are outside its view.
pub fn living_room_gltf() -> String {
    let mut b = GltfBuilder::new();
    let wood_tex = b.texture_png("wood_planks", 256, 256, &wood_planks_texture(256));
    let rug_tex = b.texture_png("rug", 128, 128, &rug_texture(128));
    let painting_tex = b.texture_png("painting", 128, 96, &painting_texture(128, 96));
    let floor_mat = b.textured_material("floor_wood", [1.0; 3], wood_tex, false);
    let rug_mat = b.textured_material("rug", [1.0; 3], rug_tex, false);
    let painting_mat = b.textured_material("painting", [1.0; 3], painting_tex, false);
    let mats = RoomMaterials {
        wall: b.material("wall_plaster", [0.75, 0.72, 0.66], [0.0; 3], false),
        ceiling: b.material("ceiling", [0.8, 0.8, 0.78], [0.0; 3], false),
        wood_light: b.material("wood_light", [0.55, 0.38, 0.22], [0.0; 3], false),
        wood_dark: b.material("wood_dark", [0.22, 0.13, 0.08], [0.0; 3], false),
        fabric_couch: b.material("fabric_couch", [0.18, 0.3, 0.38], [0.0; 3], false),
        fabric_cushion: b.material("fabric_cushion", [0.7, 0.5, 0.2], [0.0; 3], false),
        fabric_chair: b.material("fabric_chair", [0.55, 0.2, 0.15], [0.0; 3], false),
        metal: b.material("metal_dark", [0.12, 0.12, 0.12], [0.0; 3], false),
        black: b.material("black", [0.03, 0.03, 0.03], [0.0; 3], false),
        screen: b.material("screen", [0.01, 0.01, 0.012], [0.0; 3], false),
        cream: b.material("lamp_shade", [0.85, 0.8, 0.68], [0.0; 3], true),
        pot: b.material("terracotta", [0.6, 0.3, 0.18], [0.0; 3], false),
        leaves: b.material("leaves", [0.12, 0.35, 0.1], [0.0; 3], false),
        book: [
            b.material("book_red", [0.5, 0.08, 0.06], [0.0; 3], false),
            b.material("book_blue", [0.08, 0.15, 0.4], [0.0; 3], false),
            b.material("book_green", [0.1, 0.32, 0.15], [0.0; 3], false),
            b.material("book_cream", [0.8, 0.75, 0.6], [0.0; 3], false),
        ],
        curtain: b.material("curtain", [0.7, 0.66, 0.55], [0.0; 3], true),
        frame: b.material("frame_gilt", [0.6, 0.45, 0.15], [0.0; 3], false),
        picture: b.material("picture", [0.3, 0.45, 0.55], [0.0; 3], false),
    };
    let light = b.material(
        "light",
        [0.78, 0.78, 0.78],
        LIVING_ROOM_LIGHT_EMISSION,
        false,
    );

    room_shell(&mut b, &mats, floor_mat);
    room_furniture(&mut b, &mats, rug_mat, painting_mat);

    // The light: 5.5 m outside the window's centre, 34 degrees above it, facing back through
    // it like a low sun: its (soft-edged) patch crosses the floor toward the couch.
    let (wlo, whi) = (
        DVec3::from(Vec3::from(LIVING_ROOM_WINDOW_MIN)),
        DVec3::from(Vec3::from(LIVING_ROOM_WINDOW_MAX)),
    );
    let window_centre = 0.5 * (wlo + whi);
    let to_light = DVec3::new(34f64.to_radians().cos(), 34f64.to_radians().sin(), 0.0);
    let centre = window_centre + 5.5 * to_light;
    let mut l = MeshData::default();
    l.quad(
        light_quad(centre, -to_light, (2.0, 1.5)),
        [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
    );
    place(&mut b, LIGHT_NAME, &l, light);

    b.camera(
        "camera",
        [2.6, 1.7, 2.35],
        [-1.0, 0.3, -1.0],
        [0.0, 1.0, 0.0],
        55f32.to_radians(),
    );
    b.to_json_string()
}

/// Floor, ceiling, walls (the right one around the window), window reveal and frame, door.
fn room_shell(b: &mut GltfBuilder, mats: &RoomMaterials, floor_mat: usize) {
    let (lo, hi) = (
        DVec3::from(Vec3::from(LIVING_ROOM_MIN)),
        DVec3::from(Vec3::from(LIVING_ROOM_MAX)),
    );
    let (wlo, whi) = (
        DVec3::from(Vec3::from(LIVING_ROOM_WINDOW_MIN)),
        DVec3::from(Vec3::from(LIVING_ROOM_WINDOW_MAX)),
    );
    let v = DVec3::new;

    // Floor with UVs in metres / 1.6 (one texture repeat per 1.6 m).
    let mut floor = MeshData::default();
    let corners = [
        v(lo.x, 0.0, lo.z),
        v(lo.x, 0.0, hi.z),
        v(hi.x, 0.0, hi.z),
        v(hi.x, 0.0, lo.z),
    ];
    floor.quad(corners, corners.map(|p| [p.x / 1.6, p.z / 1.6]));
    assert!(floor.normals[0].y > 0.0);
    let m = floor.emit(b, "floor", floor_mat, true);
    b.node("floor", m, [0.0; 3]);

    let mut ceiling = MeshData::default();
    ceiling.quad_facing(
        [
            v(lo.x, hi.y, lo.z),
            v(hi.x, hi.y, lo.z),
            v(hi.x, hi.y, hi.z),
            v(lo.x, hi.y, hi.z),
        ],
        DVec3::NEG_Y,
    );
    place(b, "ceiling", &ceiling, mats.ceiling);

    let mut walls = MeshData::default();
    // Back (z = lo.z), front (z = hi.z), left (x = lo.x).
    walls.quad_facing(
        [
            v(lo.x, 0.0, lo.z),
            v(hi.x, 0.0, lo.z),
            v(hi.x, hi.y, lo.z),
            v(lo.x, hi.y, lo.z),
        ],
        DVec3::Z,
    );
    walls.quad_facing(
        [
            v(lo.x, 0.0, hi.z),
            v(hi.x, 0.0, hi.z),
            v(hi.x, hi.y, hi.z),
            v(lo.x, hi.y, hi.z),
        ],
        DVec3::NEG_Z,
    );
    walls.quad_facing(
        [
            v(lo.x, 0.0, lo.z),
            v(lo.x, 0.0, hi.z),
            v(lo.x, hi.y, hi.z),
            v(lo.x, hi.y, lo.z),
        ],
        DVec3::X,
    );
    // Right wall (x = hi.x) from four quads around the window.
    let x = hi.x;
    for (y0, y1, z0, z1) in [
        (0.0, wlo.y, lo.z, hi.z),
        (whi.y, hi.y, lo.z, hi.z),
        (wlo.y, whi.y, lo.z, wlo.z),
        (wlo.y, whi.y, whi.z, hi.z),
    ] {
        walls.quad_facing(
            [v(x, y0, z0), v(x, y0, z1), v(x, y1, z1), v(x, y1, z0)],
            DVec3::NEG_X,
        );
    }
    // The reveal: the window opening's four sides through the wall's thickness.
    let xo = x + WALL_THICKNESS;
    walls.quad_facing(
        [
            v(x, wlo.y, wlo.z),
            v(xo, wlo.y, wlo.z),
            v(xo, wlo.y, whi.z),
            v(x, wlo.y, whi.z),
        ],
        DVec3::Y,
    );
    walls.quad_facing(
        [
            v(x, whi.y, wlo.z),
            v(xo, whi.y, wlo.z),
            v(xo, whi.y, whi.z),
            v(x, whi.y, whi.z),
        ],
        DVec3::NEG_Y,
    );
    walls.quad_facing(
        [
            v(x, wlo.y, wlo.z),
            v(xo, wlo.y, wlo.z),
            v(xo, whi.y, wlo.z),
            v(x, whi.y, wlo.z),
        ],
        DVec3::Z,
    );
    walls.quad_facing(
        [
            v(x, wlo.y, whi.z),
            v(xo, wlo.y, whi.z),
            v(xo, whi.y, whi.z),
            v(x, whi.y, whi.z),
        ],
        DVec3::NEG_Z,
    );
    place(b, "walls", &walls, mats.wall);

    // Window frame: a cross of bars in the middle of the reveal, plus a sill.
    let mut frame = MeshData::default();
    let (xm, t) = (x + 0.1, 0.025);
    let (zc, yc) = (0.5 * (wlo.z + whi.z), 0.5 * (wlo.y + whi.y) + 0.15);
    frame.cuboid(v(xm - t, wlo.y, zc - t), v(xm + t, whi.y, zc + t));
    frame.cuboid(v(xm - t, yc - t, wlo.z), v(xm + t, yc + t, whi.z));
    frame.cuboid(
        v(x - 0.06, wlo.y - 0.03, wlo.z - 0.08),
        v(x + 0.02, wlo.y, whi.z + 0.08),
    );
    place(b, "window_frame", &frame, mats.wood_light);

    // Baseboards and a door on the front wall (decor, not furniture).
    let mut trim = MeshData::default();
    trim.cuboid(v(lo.x, 0.0, lo.z), v(hi.x, 0.08, lo.z + 0.015));
    trim.cuboid(v(lo.x, 0.0, lo.z), v(lo.x + 0.015, 0.08, hi.z));
    trim.cuboid(v(lo.x, 0.0, hi.z - 0.015), v(hi.x, 0.08, hi.z));
    trim.cuboid(v(-1.4, 0.0, hi.z - 0.03), v(-0.5, 2.1, hi.z));
    place(b, "trim_and_door", &trim, mats.wood_dark);
}

/// The furniture pieces (see [`LIVING_ROOM_FURNITURE_PIECES`]).
fn room_furniture(b: &mut GltfBuilder, mats: &RoomMaterials, rug_mat: usize, painting_mat: usize) {
    let v = DVec3::new;
    let y_rot = |a: f64| a.to_radians();

    // Couch along the left wall facing +x (toward the window), a dark gap behind it.
    let mut frame = MeshData::default();
    frame.cuboid(v(-0.45, 0.1, -1.1), v(0.45, 0.42, 1.1)); // base
    frame.cuboid(v(0.2, 0.1, -1.1), v(0.45, 0.95, 1.1)); // back
    frame.cuboid(v(-0.45, 0.1, -1.1), v(0.45, 0.65, -0.9)); // arms
    frame.cuboid(v(-0.45, 0.1, 0.9), v(0.45, 0.65, 1.1));
    let mut legs = MeshData::default();
    for (x, z) in [(-0.4, -1.05), (0.4, -1.05), (0.4, 1.05), (-0.4, 1.05)] {
        legs.cuboid(v(x - 0.03, 0.0, z - 0.03), v(x + 0.03, 0.1, z + 0.03));
    }
    let mut cushions = MeshData::default();
    for z in [-0.88, 0.0] {
        cushions.cuboid(v(-0.42, 0.42, z + 0.01), v(0.2, 0.52, z + 0.87));
    }
    for z in [-0.6, 0.6] {
        cushions.cuboid_yaw(v(0.12, 0.68, z), v(0.08, 0.2, 0.22), 0.0);
    }
    furniture(
        b,
        "couch",
        v(-2.33, 0.0, 0.0),
        PI,
        vec![
            ("frame", frame, mats.fabric_couch, false),
            ("legs", legs, mats.wood_dark, false),
            ("cushions", cushions, mats.fabric_cushion, false),
        ],
    );

    furniture(
        b,
        "coffee_table",
        v(-1.3, 0.0, 0.0),
        0.0,
        vec![(
            "wood",
            {
                let mut m = table(v(0.6, 0.42, 1.1), 0.05, 0.05);
                m.cuboid(v(-0.25, 0.12, -0.5), v(0.25, 0.14, 0.5)); // lower shelf
                m
            },
            mats.wood_light,
            false,
        )],
    );

    // Rug under the coffee table, textured on top.
    let mut rug = MeshData::default();
    let (rx, rz, ry) = (0.95, 1.3, 0.012);
    rug.quad(
        [
            v(-rx, ry, -rz),
            v(-rx, ry, rz),
            v(rx, ry, rz),
            v(rx, ry, -rz),
        ],
        [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
    );
    rug.cuboid_faces(
        v(-rx, 0.0, -rz),
        v(rx, ry, rz),
        [true, true, false, false, true, true],
    );
    let n = rug.uvs.len();
    for uv in &mut rug.uvs[4..n] {
        *uv = [0.0, 0.0]; // sides: the border colour
    }
    furniture(
        b,
        "rug",
        v(-1.2, 0.0, 0.0),
        0.0,
        vec![("rug", rug, rug_mat, true)],
    );

    // TV stand and TV against the back wall, facing +z.
    let mut stand = MeshData::default();
    stand.cuboid(v(-0.22, 0.05, -0.9), v(0.22, 0.5, 0.9));
    let mut stand_legs = MeshData::default();
    for z in [-0.85, 0.85] {
        stand_legs.cuboid(v(-0.2, 0.0, z - 0.03), v(0.2, 0.05, z + 0.03));
    }
    furniture(
        b,
        "tv_stand",
        v(-1.55, 0.0, -2.27),
        -FRAC_PI_2,
        vec![
            ("cabinet", stand, mats.wood_dark, false),
            ("feet", stand_legs, mats.metal, false),
        ],
    );
    let mut tv = MeshData::default();
    tv.cuboid(v(-0.03, 0.62, -0.72), v(0.03, 1.38, 0.72));
    tv.cuboid(v(-0.12, 0.5, -0.2), v(0.12, 0.52, 0.2));
    tv.cuboid(v(-0.02, 0.52, -0.04), v(0.02, 0.62, 0.04));
    let mut screen = MeshData::default();
    screen.quad_facing(
        [
            v(0.031, 0.65, -0.69),
            v(0.031, 0.65, 0.69),
            v(0.031, 1.35, 0.69),
            v(0.031, 1.35, -0.69),
        ],
        DVec3::X,
    );
    furniture(
        b,
        "tv",
        v(-1.55, 0.0, -2.27),
        -FRAC_PI_2,
        vec![
            ("body", tv, mats.black, false),
            ("screen", screen, mats.screen, false),
        ],
    );

    // Bookshelf against the back wall, books on its shelves (four colours).
    let mut shelf = MeshData::default();
    let (sw, sd, sh) = (1.2, 0.34, 1.9);
    shelf.cuboid(v(-sw / 2.0, 0.0, 0.0), v(-sw / 2.0 + 0.03, sh, sd));
    shelf.cuboid(v(sw / 2.0 - 0.03, 0.0, 0.0), v(sw / 2.0, sh, sd));
    shelf.cuboid(v(-sw / 2.0, 0.0, 0.0), v(sw / 2.0, sh, 0.015));
    let levels = [0.05, 0.5, 0.95, 1.4, 1.87];
    for y in levels {
        shelf.cuboid(
            v(-sw / 2.0 + 0.03, y, 0.015),
            v(sw / 2.0 - 0.03, y + 0.03, sd),
        );
    }
    furniture(
        b,
        "bookshelf",
        v(0.05, 0.0, -2.5),
        0.0,
        vec![("frame", shelf, mats.wood_light, false)],
    );
    let mut books: [MeshData; 4] = Default::default();
    let mut k = 0i64;
    for (level, &y) in levels[..4].iter().enumerate() {
        let mut x = -sw / 2.0 + 0.05;
        let end = sw / 2.0 - 0.05 - if level == 1 { 0.35 } else { 0.0 };
        while x < end - 0.05 {
            let w = 0.025 + 0.025 * rand01(k, 400);
            let h = 0.22 + 0.14 * rand01(k, 401);
            let d = 0.2 + 0.08 * rand01(k, 402);
            let c = (hash(k as u32 ^ 0x5bd1) % 4) as usize;
            let lean = if rand01(k, 403) < 0.08 { 0.2 } else { 0.0 };
            books[c].cuboid_yaw(
                v(x + w / 2.0, 0.0, 0.03 + d / 2.0),
                v(w / 2.0, h / 2.0, d / 2.0),
                0.0,
            );
            let start = books[c].positions.len() - 24;
            let rot = DQuat::from_rotation_z(lean);
            for i in start..books[c].positions.len() {
                let p = books[c].positions[i];
                books[c].positions[i] = rot * (p + v(0.0, h / 2.0, 0.0) - v(x + w / 2.0, 0.0, 0.0))
                    + v(x + w / 2.0, y + 0.03, 0.0);
                books[c].normals[i] = rot * books[c].normals[i];
            }
            x += w + 0.003 + if lean > 0.0 { 0.05 } else { 0.0 };
            k += 1;
        }
    }
    let [b0, b1, b2, b3] = books;
    furniture(
        b,
        "books",
        v(0.05, 0.0, -2.5),
        0.0,
        vec![
            ("red", b0, mats.book[0], false),
            ("blue", b1, mats.book[1], false),
            ("green", b2, mats.book[2], false),
            ("cream", b3, mats.book[3], false),
        ],
    );

    // Dining table in the window light, four chairs.
    let table_pos = v(1.55, 0.0, -1.55);
    furniture(
        b,
        "dining_table",
        table_pos,
        0.0,
        vec![(
            "wood",
            table(v(1.5, 0.76, 0.9), 0.05, 0.07),
            mats.wood_light,
            false,
        )],
    );
    for (k, (dx, dz, yaw)) in [
        (-0.4, 0.62, 0.0),
        (0.4, 0.62, 0.0),
        (-0.4, -0.62, 180.0),
        (0.4, -0.62, 180.0),
    ]
    .into_iter()
    .enumerate()
    {
        furniture(
            b,
            &format!("chair_{}", k + 1),
            table_pos + v(dx, 0.0, dz),
            y_rot(yaw + 8.0 * (k as f64 - 1.5)),
            vec![("wood", chair(), mats.wood_dark, false)],
        );
    }
    // Pendant lamp over the dining table (not a light source).
    let mut cord = MeshData::default();
    cord.frustum(v(0.0, 1.95, 0.0), 0.008, 0.008, 0.75, 8);
    let mut shade = MeshData::default();
    shade.frustum(v(0.0, 1.7, 0.0), 0.25, 0.06, 0.25, 48);
    furniture(
        b,
        "pendant_lamp",
        table_pos,
        0.0,
        vec![
            ("cord", cord, mats.metal, false),
            ("shade", shade, mats.cream, false),
        ],
    );
    // A vase on the table.
    let mut vase = MeshData::default();
    vase.surface(32, 24, true, Facing::Outward, |i, j| {
        let theta = TAU * i as f64 / 32.0;
        let t = j as f64 / 24.0;
        let r = if j == 0 || j == 24 {
            0.0
        } else {
            0.05 + 0.04 * (PI * t).sin() - 0.025 * smoothstep(0.7, 1.0, t)
        };
        v(
            r * theta.cos(),
            0.76 + 0.3 * t.clamp(0.0, 1.0),
            -r * theta.sin(),
        )
    });
    furniture(
        b,
        "vase",
        table_pos + v(0.2, 0.0, 0.1),
        0.0,
        vec![("vase", vase, mats.pot, false)],
    );

    // Armchair in the front-left, turned toward the coffee table.
    let mut arm = MeshData::default();
    arm.cuboid(v(-0.42, 0.12, -0.4), v(0.42, 0.42, 0.4));
    arm.cuboid(v(-0.42, 0.12, 0.22), v(0.42, 0.95, 0.42));
    arm.cuboid(v(-0.42, 0.12, -0.4), v(-0.3, 0.62, 0.42));
    arm.cuboid(v(0.3, 0.12, -0.4), v(0.42, 0.62, 0.42));
    for (x, z) in [(-0.36, -0.34), (0.36, -0.34), (0.36, 0.36), (-0.36, 0.36)] {
        arm.cuboid(v(x - 0.03, 0.0, z - 0.03), v(x + 0.03, 0.12, z + 0.03));
    }
    furniture(
        b,
        "armchair",
        v(-1.1, 0.0, 1.65),
        y_rot(-25.0),
        vec![("fabric", arm, mats.fabric_chair, false)],
    );

    // Cabinet (sideboard) against the left wall at the back, with handles.
    let mut cab = MeshData::default();
    cab.cuboid(v(-0.22, 0.08, -0.55), v(0.22, 0.85, 0.55));
    for (x, z) in [(-0.18, -0.5), (0.18, -0.5), (0.18, 0.5), (-0.18, 0.5)] {
        cab.cuboid(v(x - 0.02, 0.0, z - 0.02), v(x + 0.02, 0.08, z + 0.02));
    }
    let mut handles = MeshData::default();
    for z in [-0.05, 0.05] {
        handles.cuboid(v(0.22, 0.55, z - 0.01), v(0.24, 0.7, z + 0.01));
    }
    furniture(
        b,
        "cabinet",
        v(-2.78, 0.0, -1.9),
        0.0,
        vec![
            ("body", cab, mats.wood_dark, false),
            ("handles", handles, mats.metal, false),
        ],
    );

    // Floor lamp in the front-left corner, side table at the couch's end.
    let mut lamp = MeshData::default();
    lamp.frustum(v(0.0, 0.0, 0.0), 0.16, 0.16, 0.03, 32);
    lamp.frustum(v(0.0, 0.03, 0.0), 0.015, 0.015, 1.4, 12);
    let mut lamp_shade = MeshData::default();
    lamp_shade.frustum(v(0.0, 1.35, 0.0), 0.22, 0.15, 0.3, 48);
    furniture(
        b,
        "floor_lamp",
        v(-2.6, 0.0, 2.1),
        0.0,
        vec![
            ("stand", lamp, mats.metal, false),
            ("shade", lamp_shade, mats.cream, false),
        ],
    );
    let mut side = MeshData::default();
    side.frustum(v(0.0, 0.0, 0.0), 0.2, 0.2, 0.03, 32);
    side.frustum(v(0.0, 0.03, 0.0), 0.03, 0.03, 0.5, 12);
    side.frustum(v(0.0, 0.53, 0.0), 0.25, 0.25, 0.03, 48);
    furniture(
        b,
        "side_table",
        v(-2.55, 0.0, 1.45),
        0.0,
        vec![("wood", side, mats.wood_light, false)],
    );

    // Plants: pots with foliage, one in the sunlit back-right corner, one front-left.
    for (name, pos, seed, scale) in [
        ("plant_1", v(2.4, 0.0, -2.1), 500u32, 1.0),
        ("plant_2", v(-0.85, 0.0, -2.15), 510, 0.8),
    ] {
        let mut pot = MeshData::default();
        pot.frustum(
            v(0.0, 0.0, 0.0),
            0.14 * scale,
            0.19 * scale,
            0.38 * scale,
            32,
        );
        let leaves = foliage(v(0.0, 0.35 * scale, 0.0), 16, 0.6 * scale, seed);
        furniture(
            b,
            name,
            pos,
            0.0,
            vec![
                ("pot", pot, mats.pot, false),
                ("leaves", leaves, mats.leaves, false),
            ],
        );
    }

    // Painting (textured) on the back wall above the dining table; a picture frame above
    // the couch.
    let mut pframe = MeshData::default();
    pframe.cuboid(v(-0.62, -0.47, 0.0), v(0.62, -0.41, 0.04));
    pframe.cuboid(v(-0.62, 0.41, 0.0), v(0.62, 0.47, 0.04));
    pframe.cuboid(v(-0.62, -0.41, 0.0), v(-0.56, 0.41, 0.04));
    pframe.cuboid(v(0.56, -0.41, 0.0), v(0.62, 0.41, 0.04));
    let mut canvas = MeshData::default();
    canvas.quad(
        [
            v(-0.56, 0.41, 0.02),
            v(-0.56, -0.41, 0.02),
            v(0.56, -0.41, 0.02),
            v(0.56, 0.41, 0.02),
        ],
        [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
    );
    furniture(
        b,
        "painting",
        v(1.4, 1.65, -2.5),
        0.0,
        vec![
            ("frame", pframe, mats.frame, false),
            ("canvas", canvas, painting_mat, true),
        ],
    );
    let mut small = MeshData::default();
    small.cuboid(v(-0.25, -0.2, 0.0), v(0.25, 0.2, 0.03));
    let mut photo = MeshData::default();
    photo.quad_facing(
        [
            v(-0.2, -0.15, 0.031),
            v(0.2, -0.15, 0.031),
            v(0.2, 0.15, 0.031),
            v(-0.2, 0.15, 0.031),
        ],
        DVec3::Z,
    );
    furniture(
        b,
        "picture_frame",
        v(-3.0, 1.55, 0.0),
        y_rot(90.0),
        vec![
            ("frame", small, mats.wood_dark, false),
            ("picture", photo, mats.picture, false),
        ],
    );

    // Curtains on both sides of the window.
    let (wlo, whi) = (LIVING_ROOM_WINDOW_MIN, LIVING_ROOM_WINDOW_MAX);
    let (wz0, wz1) = (wlo[2] as f64, whi[2] as f64);
    furniture(
        b,
        "curtain_left",
        DVec3::ZERO,
        0.0,
        vec![(
            "cloth",
            curtain(3.0, wz0 - 0.5, wz0 + 0.05, 0.3, 2.45),
            mats.curtain,
            false,
        )],
    );
    furniture(
        b,
        "curtain_right",
        DVec3::ZERO,
        0.0,
        vec![(
            "cloth",
            curtain(3.0, wz1 - 0.05, wz1 + 0.55, 0.3, 2.45),
            mats.curtain,
            false,
        )],
    );

    // Ottoman between the couch and the dining area.
    let mut ottoman = MeshData::default();
    ottoman.cuboid(v(-0.25, 0.06, -0.25), v(0.25, 0.4, 0.25));
    for (x, z) in [(-0.2, -0.2), (0.2, -0.2), (0.2, 0.2), (-0.2, 0.2)] {
        ottoman.cuboid(v(x - 0.02, 0.0, z - 0.02), v(x + 0.02, 0.06, z + 0.02));
    }
    furniture(
        b,
        "ottoman",
        v(-0.35, 0.0, -0.9),
        y_rot(20.0),
        vec![("fabric", ottoman, mats.fabric_chair, false)],
    );

    // A low shelf with storage boxes under the window.
    let mut low = MeshData::default();
    low.cuboid(v(-0.18, 0.0, -0.6), v(0.18, 0.45, 0.6));
    let mut boxes = MeshData::default();
    for (k, z) in [-0.35, 0.05, 0.4].into_iter().enumerate() {
        boxes.cuboid_yaw(
            v(0.0, 0.45 + 0.06 + 0.02 * k as f64, z),
            v(0.1, 0.06 + 0.02 * k as f64, 0.12),
            0.2 * k as f64,
        );
    }
    furniture(
        b,
        "low_shelf",
        v(2.78, 0.0, -0.9),
        0.0,
        vec![
            ("body", low, mats.wood_light, false),
            ("boxes", boxes, mats.book[3], false),
        ],
    );
}
