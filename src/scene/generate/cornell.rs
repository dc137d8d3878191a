//! Built-in scenes: the Cornell box (published Cornell University measurements, converted
//! to metres) and a closed "furnace" box for energy-conservation tests.

use super::builder::{closed_box, orient_quad, GltfBuilder};

/// A quad in millimetres, as listed in the Cornell Box Data.
type QuadMm = [[f64; 3]; 4];

const FLOOR: QuadMm = [
    [552.8, 0.0, 0.0],
    [0.0, 0.0, 0.0],
    [0.0, 0.0, 559.2],
    [549.6, 0.0, 559.2],
];
const CEILING: QuadMm = [
    [556.0, 548.8, 0.0],
    [556.0, 548.8, 559.2],
    [0.0, 548.8, 559.2],
    [0.0, 548.8, 0.0],
];
const BACK_WALL: QuadMm = [
    [549.6, 0.0, 559.2],
    [0.0, 0.0, 559.2],
    [0.0, 548.8, 559.2],
    [556.0, 548.8, 559.2],
];
/// At x = 0: on the camera's right (screen-right is -x for a camera looking down +z).
const RIGHT_WALL: QuadMm = [
    [0.0, 0.0, 559.2],
    [0.0, 0.0, 0.0],
    [0.0, 548.8, 0.0],
    [0.0, 548.8, 559.2],
];
/// At x ≈ 550: on the camera's left.
const LEFT_WALL: QuadMm = [
    [552.8, 0.0, 0.0],
    [549.6, 0.0, 559.2],
    [556.0, 548.8, 559.2],
    [556.0, 548.8, 0.0],
];
/// The ceiling is at y = 548.8; the emitter sits 0.1 mm below it, facing down.
const LIGHT: QuadMm = [
    [343.0, 548.7, 227.0],
    [343.0, 548.7, 332.0],
    [213.0, 548.7, 332.0],
    [213.0, 548.7, 227.0],
];

/// Short block: top, then four sides.
const SHORT_BLOCK: [QuadMm; 5] = [
    [
        [130.0, 165.0, 65.0],
        [82.0, 165.0, 225.0],
        [240.0, 165.0, 272.0],
        [290.0, 165.0, 114.0],
    ],
    [
        [290.0, 0.0, 114.0],
        [290.0, 165.0, 114.0],
        [240.0, 165.0, 272.0],
        [240.0, 0.0, 272.0],
    ],
    [
        [130.0, 0.0, 65.0],
        [130.0, 165.0, 65.0],
        [290.0, 165.0, 114.0],
        [290.0, 0.0, 114.0],
    ],
    [
        [82.0, 0.0, 225.0],
        [82.0, 165.0, 225.0],
        [130.0, 165.0, 65.0],
        [130.0, 0.0, 65.0],
    ],
    [
        [240.0, 0.0, 272.0],
        [240.0, 165.0, 272.0],
        [82.0, 165.0, 225.0],
        [82.0, 0.0, 225.0],
    ],
];

/// Tall block: top, then four sides.
const TALL_BLOCK: [QuadMm; 5] = [
    [
        [423.0, 330.0, 247.0],
        [265.0, 330.0, 296.0],
        [314.0, 330.0, 456.0],
        [472.0, 330.0, 406.0],
    ],
    [
        [423.0, 0.0, 247.0],
        [423.0, 330.0, 247.0],
        [472.0, 330.0, 406.0],
        [472.0, 0.0, 406.0],
    ],
    [
        [472.0, 0.0, 406.0],
        [472.0, 330.0, 406.0],
        [314.0, 330.0, 456.0],
        [314.0, 0.0, 456.0],
    ],
    [
        [314.0, 0.0, 456.0],
        [314.0, 330.0, 456.0],
        [265.0, 330.0, 296.0],
        [265.0, 0.0, 296.0],
    ],
    [
        [265.0, 0.0, 296.0],
        [265.0, 330.0, 296.0],
        [423.0, 330.0, 247.0],
        [423.0, 0.0, 247.0],
    ],
];

/// Camera position (mm), looking along +z with +y up.
const CAMERA_EYE: [f64; 3] = [278.0, 273.0, -800.0];
/// Focal length and film size (m) of the published camera.
const FOCAL_LENGTH: f64 = 0.035;
const FILM_SIZE: f64 = 0.025;

/// Light emitted radiance (linear RGB), as in common Cornell box renderings.
pub const LIGHT_EMISSION: [f32; 3] = [17.0, 12.0, 4.0];

/// Vertical field of view of the published camera: `2 atan(film / 2 / focal)` ≈ 39.3°.
pub fn cornell_camera_yfov() -> f32 {
    (2.0 * (FILM_SIZE / 2.0 / FOCAL_LENGTH).atan()) as f32
}

fn metres(p: [f64; 3]) -> [f32; 3] {
    p.map(|v| (v / 1000.0) as f32)
}

fn quad_metres(q: &QuadMm) -> [[f32; 3]; 4] {
    q.map(metres)
}

fn centroid(points: impl IntoIterator<Item = [f32; 3]>) -> glam::Vec3 {
    let (sum, n) = points
        .into_iter()
        .fold((glam::Vec3::ZERO, 0.0), |(s, n), p| {
            (s + glam::Vec3::from(p), n + 1.0)
        });
    sum / n
}

/// Orients a quad so its front face points toward `target` (walls) or, with
/// `away = true`, away from it (block faces).
fn orient_relative(q: [[f32; 3]; 4], target: glam::Vec3, away: bool) -> [[f32; 3]; 4] {
    let towards = target - centroid(q);
    let dir = if away { -towards } else { towards };
    orient_quad(q, dir.to_array())
}

/// The classic Cornell box as glTF JSON text, in metres: white floor, ceiling and back
/// wall, red left wall, green right wall, short and tall white blocks, a downward-facing
/// area light (Le = 17, 12, 4) and the published camera. Walls face the interior, block
/// faces face outward. Deterministic; `scenes/cornell_box.gltf` is exactly this output.
pub fn cornell_box_gltf() -> String {
    let mut b = GltfBuilder::new();
    let white = b.material("white", [0.725, 0.71, 0.68], [0.0; 3], false);
    let red = b.material("red", [0.63, 0.065, 0.05], [0.0; 3], false);
    let green = b.material("green", [0.14, 0.45, 0.091], [0.0; 3], false);
    let light = b.material("light", [0.78, 0.78, 0.78], LIGHT_EMISSION, false);

    let walls = [FLOOR, CEILING, BACK_WALL, LEFT_WALL, RIGHT_WALL].map(|q| quad_metres(&q));
    let interior = centroid(walls.iter().flatten().copied());
    for (name, quad, material) in [
        ("floor", walls[0], white),
        ("ceiling", walls[1], white),
        ("back_wall", walls[2], white),
        ("left_wall_red", walls[3], red),
        ("right_wall_green", walls[4], green),
    ] {
        let mesh = b.quad(name, orient_relative(quad, interior, false), material);
        b.node(name, mesh, [0.0; 3]);
    }

    for (name, faces) in [("short_block", &SHORT_BLOCK), ("tall_block", &TALL_BLOCK)] {
        let faces = faces.map(|q| quad_metres(&q));
        let center = centroid(faces.iter().flatten().copied());
        let faces = faces.map(|q| orient_relative(q, center, true));
        let mesh = b.quads(name, &faces, white);
        b.node(name, mesh, [0.0; 3]);
    }

    let light_quad = orient_quad(quad_metres(&LIGHT), [0.0, -1.0, 0.0]);
    let light_mesh = b.quad("light", light_quad, light);
    b.node("light", light_mesh, [0.0; 3]);

    let eye = metres(CAMERA_EYE);
    b.camera(
        "camera",
        eye,
        [eye[0], eye[1], 0.0],
        [0.0, 1.0, 0.0],
        cornell_camera_yfov(),
    );
    b.to_json_string()
}

/// A closed cube `[-size/2, size/2]^3` whose six faces (double-sided, facing inward) all
/// have grey albedo `albedo` and emit grey radiance `emission`, viewed by a perspective
/// camera at the centre looking down -z (yfov 60°). Inside, the radiance converges to
/// `emission / (1 - albedo)`.
pub fn furnace_box_gltf(albedo: f32, emission: f32, size: f32) -> String {
    let mut b = GltfBuilder::new();
    let material = b.material("furnace", [albedo; 3], [emission; 3], true);
    let h = 0.5 * size;
    let mesh = closed_box(&mut b, "furnace_box", [-h; 3], [h; 3], material, true);
    b.node("furnace_box", mesh, [0.0; 3]);
    b.camera(
        "camera",
        [0.0; 3],
        [0.0, 0.0, -1.0],
        [0.0, 1.0, 0.0],
        60f32.to_radians(),
    );
    b.to_json_string()
}
