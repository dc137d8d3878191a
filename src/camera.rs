//! The camera: where a frame is seen from. The renderer takes one per frame; headless runs, camera
//! paths and the window's controller decide which.

use glam::{Mat4, Vec3};
use serde::Serialize;

use crate::scene_gpu::SceneInfo;
use crate::settings::CameraOverride;

/// `p + by`, added in f64 (the file's coordinates of a far scene and the renderer's differ by a
/// large `by`: the sum is rounded once).
fn moved(p: Vec3, by: Vec3) -> Vec3 {
    (p.as_dvec3() + by.as_dvec3()).as_vec3()
}

/// A pinhole camera: position and an orthonormal basis (right-handed, looking down `forward`).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Camera {
    pub position: Vec3,
    pub forward: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    /// Vertical field of view (radians).
    pub yfov: f32,
    /// Where it came from: "scene camera", "command line", "automatic (no camera in the scene)", …
    pub source: &'static str,
}

impl Camera {
    /// A camera at the origin of `t` looking down its local −Z with +Y up (glTF's convention).
    pub fn from_transform(t: Mat4, yfov: f32, source: &'static str) -> Self {
        let eye = t.w_axis.truncate();
        Self::from_directions(eye, -t.z_axis.truncate(), t.y_axis.truncate(), yfov, source)
    }

    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, yfov: f32, source: &'static str) -> Self {
        // Halves first: the difference of two finite points can overflow where its direction does not.
        Self::from_directions(eye, target * 0.5 - eye * 0.5, up, yfov, source)
    }

    /// The basis from a view direction and an up hint, finite for any finite input: a direction
    /// whose length overflows or underflows f32 is rescaled before it is normalised, a zero one
    /// looks down −Z, and an up hint parallel to it (or zero) is replaced by a perpendicular one.
    /// (The inputs' own checks name what is wrong, `Keyframe::check` and the command line's; this
    /// keeps a camera interpolated or derived from extreme bounds from turning the image to NaN.)
    fn from_directions(position: Vec3, forward: Vec3, up: Vec3, yfov: f32, source: &'static str) -> Self {
        let forward = unit(forward).unwrap_or(Vec3::NEG_Z);
        let right = unit(forward.cross(unit(up).unwrap_or(Vec3::Y)))
            .filter(|r| r.length_squared() > 0.5)
            .unwrap_or_else(|| forward.any_orthonormal_vector());
        let up = right.cross(forward);
        Self { position, forward, right, up, yfov, source }
    }

    /// Eye, view direction, up and field of view on one line, in the command line's terms
    /// (`--eye`, `--fov` in degrees), for logs.
    pub fn describe(&self) -> String {
        // (+ 0.0: -0 prints as 0.)
        let v = |v: Vec3| format!("[{}, {}, {}]", v.x + 0.0, v.y + 0.0, v.z + 0.0);
        format!("eye {}, forward {}, up {}, fov {:.2}°", v(self.position), v(self.forward), v(self.up), self.yfov.to_degrees())
    }

    /// Whether every number of the camera is finite (what the renderer requires of a frame's camera).
    pub fn is_finite(&self) -> bool {
        self.position.is_finite() && self.forward.is_finite() && self.right.is_finite() && self.up.is_finite() && self.yfov.is_finite()
    }

    /// The camera a run starts from: the command line's, else the scene's, else one that frames the
    /// scene's bounds from +z.
    pub fn initial(scene: &SceneInfo, camera: Option<&CameraOverride>) -> Self {
        if let Some(c) = camera {
            // Given in the file's coordinates; the scene may have been moved (Scene::origin).
            let (eye, target) = (moved(c.eye, -scene.origin), moved(c.target, -scene.origin));
            return Self::look_at(eye, target, c.up, c.yfov_degrees.to_radians(), "command line");
        }
        if let Some((transform, yfov)) = scene.camera {
            return Self::from_transform(transform, yfov, "scene camera");
        }
        // In f64: the bounds' diagonal of a scene spanning more than ~1e19 overflows f32.
        let (lo, hi) = (scene.bounds.0.as_dvec3(), scene.bounds.1.as_dvec3());
        let centre = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(1e-3);
        let yfov = 45f32.to_radians();
        let distance = radius / (f64::from(yfov) * 0.5).tan() * 1.1;
        let eye = (centre + glam::DVec3::Z * distance).as_vec3().min(Vec3::splat(f32::MAX));
        Self::look_at(eye, centre.as_vec3(), Vec3::Y, yfov, "automatic (no camera in the scene)")
    }

    /// This camera as a command-line camera (`--eye`, `--target`, `--up`, `--fov`: what reference
    /// settings record), from which [`Camera::initial`] makes it again: in the file's coordinates,
    /// `origin` being the scene's [`crate::scene::Scene::origin`].
    pub fn as_override(&self, origin: Vec3) -> CameraOverride {
        let c = self.moved(origin);
        CameraOverride { eye: c.position, target: c.target_point(), up: c.up, yfov_degrees: c.yfov.to_degrees() }
    }

    /// This camera moved by `by` (computed in f64): `moved(origin)` from the renderer's coordinates
    /// to the file's, `moved(-origin)` back.
    pub fn moved(&self, by: Vec3) -> Self {
        Self { position: moved(self.position, by), ..*self }
    }

    /// A point the camera looks at, written where a camera is saved as eye and target: one unit
    /// ahead within 1024 of the origin (rounding then turns the view by at most ~1e-4 rad, a tenth
    /// of a pixel at 4K; and records of references made before stay equal), and beyond that as far
    /// ahead as the eye is from the origin, so that rounding the target to f32 keeps the direction
    /// (one unit ahead of an eye at 3e7 turned the view by 16° once saved and read back); at most
    /// 1e17 ahead (an eye beyond 9e17 looking outwards can still put it past the 1e18 a camera
    /// path allows, which reading it back then refuses by name).
    pub fn target_point(&self) -> Vec3 {
        let far = self.position.abs().max_element();
        if far <= 1024.0 {
            return self.position + self.forward;
        }
        (self.position.as_dvec3() + self.forward.as_dvec3() * f64::from(far.min(1e17))).as_vec3()
    }

    /// Whether two cameras see the same image (position, orientation and field of view; the
    /// source does not count).
    pub fn same_view(&self, other: &Camera) -> bool {
        self.position == other.position && self.forward == other.forward && self.up == other.up && self.yfov == other.yfov
    }

    /// Whether any of the box `lo`..`hi` may be in view at width / height `aspect`: false only
    /// when all its corners lie behind the camera or beyond one side of the view (the window's
    /// hint that the scene has left the screen). Conservative: a box near a corner of the view
    /// but outside it can count as seen, never the reverse.
    pub fn sees_box(&self, lo: Vec3, hi: Vec3, aspect: f32) -> bool {
        let tan_y = (0.5 * self.yfov).tan();
        let tan_x = tan_y * aspect.max(0.0);
        let corners = (0..8).map(|i| {
            let c = Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            let d = c - self.position;
            (d.dot(self.right), d.dot(self.up), d.dot(self.forward))
        });
        let outside: [fn((f32, f32, f32), f32, f32) -> bool; 5] = [
            |(_, _, z), _, _| z <= 0.0,
            |(x, _, z), tx, _| x > z * tx,
            |(x, _, z), tx, _| -x > z * tx,
            |(_, y, z), _, ty| y > z * ty,
            |(_, y, z), _, ty| -y > z * ty,
        ];
        !outside.iter().any(|out| corners.clone().all(|c| out(c, tan_x, tan_y)))
    }
}

/// `v` scaled to unit length, also where its squared length overflows or underflows f32; `None`
/// for a zero or non-finite `v`.
fn unit(v: Vec3) -> Option<Vec3> {
    if !v.is_finite() {
        return None;
    }
    let m = v.abs().max_element();
    (m > 0.0).then(|| (v / m).normalize())
}

/// What makes a view from `eye` to `target` with the up hint `up` unusable: the command line's
/// --eye/--target/--up and a camera path's keyframes are checked alike, each in its own words.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ViewProblem {
    SamePoint,
    /// The distance (in f64) is outside 1e-18..=1e18: 32-bit floats square it when normalising
    /// and in the parallel test; 1e18 leaves room, far beyond any scene.
    Distance(f64),
    UpParallel,
    /// The eye (false) or the target (true) lies farther than [`MAX_CAMERA_COORDINATE`] from the
    /// origin on some axis (checked last).
    FarFromOrigin { target: bool },
}

/// The narrowest vertical field of view taken, in degrees. Narrower, tan(fov / 2) approaches the
/// spacing of 32-bit floats around 1 at a picture's pixel pitch, and below ~1e-38 it is 0: the
/// motion vectors divide by it (--fov 1e-45 made 2048 NaN samples in 32×32 pixels).
pub const MIN_FOV_DEGREES: f32 = 0.01;

/// Whether `degrees` is a field of view the renderer takes: in [[`MIN_FOV_DEGREES`], 180).
pub fn fov_ok(degrees: f32) -> bool {
    (MIN_FOV_DEGREES..180.0).contains(&degrees)
}

/// Why a run with `camera` (the command line's, if any) and `path_given` (`--camera-path`) cannot
/// start from the scene's own camera: a yfov outside [`MIN_FOV_DEGREES`], 180) degrees, as
/// `--fov` must be. None where the scene's camera is fine, absent, or replaced.
pub fn scene_camera_problem(scene: &SceneInfo, camera: Option<&CameraOverride>, path_given: bool) -> Option<String> {
    if camera.is_some() || path_given {
        return None;
    }
    let (_, yfov) = scene.camera?;
    (!fov_ok(yfov.to_degrees())).then(|| {
        format!(
            "{}: its camera's yfov {yfov} rad ({}°) must be in [{MIN_FOV_DEGREES}, 180) degrees, as --fov; fix the file, or \
             give the camera with --eye/--target (and --fov)",
            scene.path.display(),
            yfov.to_degrees()
        )
    })
}

/// The farthest from the origin an eye or target may be (a camera path's and `--eye`'s).
pub const MAX_CAMERA_COORDINATE: f32 = 1e18;

pub fn view_problem(eye: Vec3, target: Vec3, up: Vec3) -> Option<ViewProblem> {
    let d = (target.as_dvec3() - eye.as_dvec3()).length();
    if d == 0.0 {
        return Some(ViewProblem::SamePoint);
    }
    // (NaN and non-finite inputs fail the range too.)
    let Some(f) = unit(target - eye).filter(|_| (1e-18..=1e18).contains(&d)) else {
        return Some(ViewProblem::Distance(d));
    };
    // On the unit up: its squared length over- or underflows f32 for |up| beyond ~1e19 or below
    // ~1e-19 (an up of [0, 1e20, 0] was refused as parallel).
    if unit(up).is_none_or(|u| f.cross(u).length_squared() <= 1e-12) {
        return Some(ViewProblem::UpParallel);
    }
    let far = |p: Vec3| p.abs().max_element() > MAX_CAMERA_COORDINATE;
    (far(eye) || far(target)).then_some(ViewProblem::FarFromOrigin { target: !far(eye) })
}

/// One keyframe of a camera path (`--camera-path FILE.json`), and the format `O` saves the window's
/// camera in: `{"keyframes": [{"frame": 0, "eye": [x,y,z], "target": [x,y,z], "up": [0,1,0], "fov": 40}]}`
/// (`fov` vertical, in degrees).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    pub frame: u32,
    pub eye: [f32; 3],
    pub target: [f32; 3],
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    /// Vertical field of view in degrees.
    pub fov: f32,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

impl Keyframe {
    /// The keyframe that reproduces `camera`.
    pub fn of(camera: &Camera, frame: u32) -> Self {
        Self {
            frame,
            eye: camera.position.to_array(),
            target: camera.target_point().to_array(),
            up: camera.up.to_array(),
            fov: camera.yfov.to_degrees(),
        }
    }

    fn check(&self) -> Result<(), String> {
        let (eye, target, up) = (Vec3::from(self.eye), Vec3::from(self.target), Vec3::from(self.up));
        if !(eye.is_finite() && target.is_finite() && up.is_finite() && self.fov.is_finite()) {
            return Err("has a number outside the 32-bit float range (beyond ±3.4e38)".into());
        }
        if !fov_ok(self.fov) {
            return Err(format!("fov {} must be in [{MIN_FOV_DEGREES}, 180) degrees", self.fov));
        }
        match view_problem(eye, target, up) {
            Some(ViewProblem::SamePoint) => return Err("eye and target are the same point".into()),
            Some(ViewProblem::Distance(d)) => {
                return Err(format!("eye and target are {d:.3e} apart; the distance must be between 1e-18 and 1e18"))
            }
            Some(ViewProblem::UpParallel) => return Err("up is parallel to the view direction (or zero)".into()),
            Some(ViewProblem::FarFromOrigin { .. }) => {
                return Err(format!("eye and target must be within {MAX_CAMERA_COORDINATE:e} of the origin"))
            }
            None => {}
        }
        Ok(())
    }

    fn camera(&self, source: &'static str) -> Camera {
        Camera::look_at(self.eye.into(), self.target.into(), self.up.into(), self.fov.to_radians(), source)
    }
}

/// A camera path: keyframes at increasing frame numbers; eye, target, up and fov are interpolated
/// linearly between them; frames before the first keyframe hold the first, frames past the last
/// hold the last.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraPath {
    pub keyframes: Vec<Keyframe>,
}

impl CameraPath {
    /// Parses and checks a path; errors say which keyframe is wrong and why.
    pub fn from_json(text: &str) -> Result<Self, String> {
        let path: CameraPath = serde_json::from_str(text).map_err(|e| e.to_string())?;
        if path.keyframes.is_empty() {
            return Err("\"keyframes\" is empty: give at least one".into());
        }
        for (i, k) in path.keyframes.iter().enumerate() {
            k.check().map_err(|e| format!("keyframe {i} (frame {}): {e}", k.frame))?;
            if i > 0 && k.frame <= path.keyframes[i - 1].frame {
                return Err(format!(
                    "keyframe {i}: frame {} does not come after the previous keyframe's frame {}",
                    k.frame,
                    path.keyframes[i - 1].frame
                ));
            }
        }
        Ok(path)
    }

    /// Reads and checks `file`; errors name the file.
    pub fn load(file: &std::path::Path) -> anyhow::Result<Self> {
        let text = String::from_utf8(crate::output::read_input(file)?).map_err(|e| anyhow::anyhow!("{}: {e}", file.display()))?;
        // A byte-order mark (Windows editors write one) is not JSON.
        Self::from_json(text.strip_prefix('\u{feff}').unwrap_or(&text)).map_err(|e| anyhow::anyhow!("{}: {e}", file.display()))
    }

    /// The path moved by `by` (eyes and targets, in f64): a path in the file's coordinates is
    /// `moved(-origin)` into those of a recentred scene ([`crate::scene::Scene::origin`]).
    pub fn moved(&self, by: Vec3) -> Self {
        let shift = |p: [f32; 3]| moved(Vec3::from(p), by).to_array();
        Self { keyframes: self.keyframes.iter().map(|k| Keyframe { eye: shift(k.eye), target: shift(k.target), ..*k }).collect() }
    }

    /// A one-keyframe path holding `camera` (what `O` writes to camera.json).
    pub fn still(camera: &Camera) -> Self {
        Self { keyframes: vec![Keyframe::of(camera, 0)] }
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a camera path serialises")
    }

    /// The frames of the first and the last keyframe (checked: increasing, at least one keyframe).
    pub fn frame_range(&self) -> (u32, u32) {
        let k = &self.keyframes;
        (k[0].frame, k[k.len() - 1].frame)
    }

    /// The camera at frame `frame` (fractional frames interpolate too).
    pub fn at(&self, frame: f32) -> Camera {
        let k = &self.keyframes;
        let first = &k[0];
        let last = &k[k.len() - 1];
        if frame <= first.frame as f32 {
            return first.camera("camera path");
        }
        if frame >= last.frame as f32 {
            return last.camera("camera path");
        }
        let i = k.iter().rposition(|x| x.frame as f32 <= frame).expect("frame is past the first keyframe");
        let (a, b) = (&k[i], &k[i + 1]);
        let t = (frame - a.frame as f32) / (b.frame - a.frame) as f32;
        let lerp = |x: [f32; 3], y: [f32; 3]| Vec3::from(x).lerp(Vec3::from(y), t);
        let eye = lerp(a.eye, b.eye);
        // The view direction interpolated itself (the same as the interpolated target minus the
        // interpolated eye, without their rounding: an eye and a target 1e-7 apart at 1 rounded
        // to one point between keyframes, and the camera panicked).
        let dir = |k: &Keyframe| Vec3::from(k.target) - Vec3::from(k.eye);
        let mut view = dir(a).lerp(dir(b), t);
        if unit(view).is_none() {
            // Eye and target cross: keep looking the way the earlier keyframe looks.
            view = dir(a);
        }
        let mut up = lerp(a.up, b.up);
        let forward = unit(view).expect("keyframes are checked: eye and target 1e-18 to 1e18 apart");
        if unit(up).is_none_or(|u| forward.cross(u).length_squared() <= 1e-12) {
            // The view passes through the up direction: roll as little as possible from the
            // earlier keyframe, whose right axis stays perpendicular to up.
            let right_a = (Vec3::from(a.target) - Vec3::from(a.eye)).cross(Vec3::from(a.up));
            up = right_a.cross(forward);
        }
        Camera::from_directions(eye, view, up, (a.fov + (b.fov - a.fov) * t).to_radians(), "camera path")
    }
}

/// A movement key (the window maps W/A/S/D, Space and Left Ctrl onto these; Shift is `fast`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MoveKey {
    Forward,
    Back,
    Left,
    Right,
    Up,
    Down,
}

/// How long each movement key was held since the last update, from the key events' own times: a
/// tap shorter than a frame still moves the camera by what was held (on lavapipe a frame can take
/// longer than a tap), and the distance does not depend on the frame rate.
#[derive(Clone, Copy, Debug, Default)]
struct HeldKeys {
    /// When each key went down (seconds on the caller's clock), while it is down.
    down_since: [Option<f64>; 6],
    /// Seconds each key was held between the last update and its release.
    held: [f64; 6],
    /// Whether each key went down after the last update.
    fresh: [bool; 6],
    /// Shift: six times faster.
    fast: bool,
}

/// A fly-through camera controller: moves along the view direction and sideways at `speed`
/// (scene units per second; ×6 with `fast`), up and down along the world's up axis, looks around
/// by yaw and pitch (pitch kept within ±89°). Until it moves, it returns exactly the camera it was
/// given, so a window that was not touched renders what a headless run renders.
#[derive(Clone, Debug)]
pub struct FlyController {
    position: Vec3,
    yaw: f32,
    pitch: f32,
    yfov: f32,
    world_up: Vec3,
    /// Horizontal axes of the yaw: forward = cos(pitch)(cos(yaw) e1 + sin(yaw) e2) + sin(pitch) up.
    e1: Vec3,
    e2: Vec3,
    /// Scene units per second.
    pub speed: f32,
    /// Radians of rotation per pixel of mouse motion.
    pub sensitivity: f32,
    keys: HeldKeys,
    /// The camera given last (scene camera, a loaded camera.json), returned as is until a move.
    exact: Option<Camera>,
    home: Camera,
}

impl FlyController {
    /// Starts at `camera` (also what Home returns to); `scene_size` (e.g. the bounds' diagonal)
    /// sets the initial speed: the scene is crossed in about five seconds. `world_up` is the
    /// scene's up, the axis the controller yaws about and flies up along: +Y for glTF (its
    /// convention) unless the user gave `--up`. The camera alone cannot tell it (a Y-up camera
    /// looking straight down with its top edge towards +Z is a level Z-up camera looking along
    /// −Y); taking the camera's own up once its pitch passed 60° rolled the horizon on a yaw and
    /// moved Space along a tilted axis. A zero or non-finite `world_up` is +Y.
    pub fn new(camera: &Camera, scene_size: f32, world_up: Vec3) -> Self {
        let world_up = unit(world_up).unwrap_or(Vec3::Y);
        let e1 = world_up.any_orthonormal_vector();
        let e2 = world_up.cross(e1);
        let mut c = Self {
            position: camera.position,
            yaw: 0.0,
            pitch: 0.0,
            yfov: camera.yfov,
            world_up,
            e1,
            e2,
            speed: (0.2 * scene_size).max(1e-6),
            sensitivity: 0.003,
            keys: HeldKeys::default(),
            exact: None,
            home: *camera,
        };
        c.set_camera(camera);
        c
    }

    /// Jumps to `camera` (returned exactly until the next move).
    pub fn set_camera(&mut self, camera: &Camera) {
        let f = camera.forward.normalize();
        self.position = camera.position;
        self.pitch = f.dot(self.world_up).clamp(-1.0, 1.0).asin().clamp(-Self::MAX_PITCH, Self::MAX_PITCH);
        // The heading: the view's horizontal part, or for a view along the axis (straight down or
        // up) the way the camera's up (down: its top edge) points, which is where it would face
        // once tilted towards the horizon.
        let along = f.dot(self.world_up);
        let level = f - along * self.world_up;
        let heading = if level.length_squared() > 1e-8 { level } else { camera.up * -along.signum() };
        self.yaw = heading.dot(self.e2).atan2(heading.dot(self.e1));
        self.yfov = camera.yfov;
        self.exact = Some(*camera);
    }

    /// A movement key is held: the camera moves on the next update.
    pub fn moving(&self) -> bool {
        self.keys.down_since.iter().any(Option::is_some)
    }

    /// Back to the camera the controller started from.
    pub fn go_home(&mut self) {
        let home = self.home;
        self.set_camera(&home);
    }

    const MAX_PITCH: f32 = 89.0 * std::f32::consts::PI / 180.0;

    fn forward(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        cp * (cy * self.e1 + sy * self.e2) + sp * self.world_up
    }

    /// The camera now.
    pub fn camera(&self) -> Camera {
        if let Some(c) = self.exact {
            return c;
        }
        let f = self.forward();
        Camera::look_at(self.position, self.position + f, self.world_up, self.yfov, "window")
    }

    /// The most one update moves for: after a stall (a minimised window, a lost key release) the
    /// camera does not jump across the scene.
    pub const MAX_STEP_SECONDS: f64 = 1.0;

    /// The least a press and release count for.
    pub const MIN_TAP_SECONDS: f64 = 1.0 / 30.0;

    /// A movement key went down or up at `t` (seconds, the same clock as `update`).
    pub fn key(&mut self, key: MoveKey, down: bool, t: f64) {
        let i = key as usize; // the index into HeldKeys' arrays, in declaration order
        match (down, self.keys.down_since[i]) {
            (true, None) => {
                self.keys.down_since[i] = Some(t);
                self.keys.fresh[i] = true;
            }
            (false, Some(since)) => {
                // Key events are read between frames, so a tap within one slow frame arrives as a
                // press and a release at the same moment: it still nudges by MIN_TAP_SECONDS.
                let least = if self.keys.fresh[i] {
                    Self::MIN_TAP_SECONDS
                } else {
                    0.0
                };
                self.keys.held[i] += (t - since).max(least);
                self.keys.down_since[i] = None;
            }
            _ => {} // key repeat, or a release without a press
        }
    }

    /// Every held key released at `t` (the window lost focus, whose releases then go elsewhere):
    /// what was held until `t` still counts (at normal speed: Shift is released too), then the
    /// camera stops.
    pub fn release_all(&mut self, t: f64) {
        for key in [MoveKey::Forward, MoveKey::Back, MoveKey::Left, MoveKey::Right, MoveKey::Up, MoveKey::Down] {
            self.key(key, false, t);
        }
        self.keys.fast = false;
    }

    /// Shift held (six times faster) or not.
    pub fn set_fast(&mut self, fast: bool) {
        self.keys.fast = fast;
    }

    /// Moves by what the keys were held since the last update, up to `t`; true when it moved.
    pub fn update(&mut self, t: f64) -> bool {
        let mut secs = [0f64; 6];
        for (i, s) in secs.iter_mut().enumerate() {
            *s = std::mem::take(&mut self.keys.held[i]);
            self.keys.fresh[i] = false;
            if let Some(since) = self.keys.down_since[i] {
                *s += (t - since).max(0.0);
                self.keys.down_since[i] = Some(t);
            }
            *s = s.min(Self::MAX_STEP_SECONDS);
        }
        let [fwd, back, left, right, up, down] = secs.map(|s| s as f32);
        let f = self.forward();
        let side = f.cross(self.world_up).normalize_or_zero();
        let speed = self.speed * if self.keys.fast { 6.0 } else { 1.0 };
        let step = ((fwd - back) * f + (right - left) * side + (up - down) * self.world_up) * speed;
        if step == Vec3::ZERO || !step.is_finite() {
            return false;
        }
        self.position += step;
        self.exact = None;
        true
    }

    /// Mouse look by (dx, dy) pixels (right: yaw right; down: pitch down); true when it turned.
    pub fn look(&mut self, dx: f32, dy: f32) -> bool {
        if dx == 0.0 && dy == 0.0 {
            return false;
        }
        self.yaw -= dx * self.sensitivity;
        self.pitch = (self.pitch - dy * self.sensitivity).clamp(-Self::MAX_PITCH, Self::MAX_PITCH);
        self.exact = None;
        true
    }

    /// Scroll: each notch up makes moving 25% faster, each notch down 25% slower.
    pub fn scroll(&mut self, notches: f32) {
        self.speed = (self.speed * 1.25f32.powf(notches)).clamp(1e-6, 1e9);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> Camera {
        Camera::look_at(Vec3::new(0.0, 1.0, 5.0), Vec3::new(0.0, 1.0, 0.0), Vec3::Y, 0.7, "test")
    }

    #[test]
    fn a_box_is_seen_unless_wholly_behind_or_beside_the_view() {
        // cam(): at (0, 1, 5) looking down -Z, 0.7 rad vertical.
        let c = cam();
        let unit = |at: Vec3| (at - Vec3::splat(0.5), at + Vec3::splat(0.5));
        let seen = |at: Vec3| {
            let (lo, hi) = unit(at);
            c.sees_box(lo, hi, 1.0)
        };
        assert!(seen(Vec3::new(0.0, 1.0, 0.0)), "straight ahead");
        assert!(seen(Vec3::new(0.0, 1.0, 5.0)), "around the camera");
        assert!(!seen(Vec3::new(0.0, 1.0, 10.0)), "behind");
        assert!(!seen(Vec3::new(20.0, 1.0, 0.0)), "far right");
        assert!(!seen(Vec3::new(-20.0, 1.0, 0.0)), "far left");
        assert!(!seen(Vec3::new(0.0, 20.0, 0.0)), "far above");
        assert!(!seen(Vec3::new(0.0, -20.0, 0.0)), "far below");
        // 5 units ahead the view is 2 tan(0.35) 5 = 3.65 wide: a box 2 units right shows at 1:1
        // and shows more at 3:1.
        assert!(seen(Vec3::new(2.0, 1.0, 0.0)));
        assert!(!seen(Vec3::new(3.0, 1.0, 0.0)));
        let (lo, hi) = unit(Vec3::new(3.0, 1.0, 0.0));
        assert!(c.sees_box(lo, hi, 3.0));
    }

    #[test]
    fn path_interpolates_and_holds() {
        let p = CameraPath::from_json(
            r#"{"keyframes": [{"frame": 0, "eye": [0,0,5], "target": [0,0,0], "fov": 40},
                              {"frame": 10, "eye": [10,0,5], "target": [10,0,0], "up": [0,1,0], "fov": 60}]}"#,
        )
        .unwrap();
        let mid = p.at(5.0);
        assert!((mid.position - Vec3::new(5.0, 0.0, 5.0)).length() < 1e-5);
        assert!((mid.forward - Vec3::NEG_Z).length() < 1e-5);
        assert!((mid.yfov.to_degrees() - 50.0).abs() < 1e-3);
        assert_eq!(p.at(25.0).position, Vec3::new(10.0, 0.0, 5.0));
        assert_eq!(p.at(0.0).position, Vec3::new(0.0, 0.0, 5.0));
    }

    #[test]
    fn bad_paths_are_refused_with_the_reason() {
        let bad = [
            (r#"{"keyframes": []}"#, "empty"),
            (r#"{"keyframes": [{"frame": 0, "eye": [0,0,0], "target": [0,0,0], "fov": 40}]}"#, "same point"),
            (r#"{"keyframes": [{"frame": 0, "eye": [0,0,1], "target": [0,0,0], "fov": 0}]}"#, "fov"),
            (r#"{"keyframes": [{"frame": 0, "eye": [0,0,1], "target": [0,0,0], "up": [0,0,1], "fov": 40}]}"#, "parallel"),
            (
                r#"{"keyframes": [{"frame": 3, "eye": [0,0,1], "target": [0,0,0], "fov": 40},
                                  {"frame": 3, "eye": [0,0,2], "target": [0,0,0], "fov": 40}]}"#,
                "does not come after",
            ),
            (r#"{"frames": []}"#, "unknown field"),
            (r#"{"keyframes": [{"frame": 0, "eye": [0,0], "target": [0,0,0], "fov": 40}]}"#, "invalid length"),
            (r#"{"keyframes": [{"frame": 0, "eye": [1e20,0,0], "target": [0,0,0], "fov": 40}]}"#, "apart"),
            (r#"{"keyframes": [{"frame": 0, "eye": [3e38,0,0], "target": [-3e38,0,0], "fov": 40}]}"#, "apart"),
            (r#"{"keyframes": [{"frame": 0, "eye": [2e18,0,0], "target": [2e18,0,1], "fov": 40}]}"#, "within 1e18"),
        ];
        for (json, want) in bad {
            let e = CameraPath::from_json(json).unwrap_err();
            assert!(e.contains(want), "{json}: {e}");
        }
    }

    /// Every keyframe is valid, but between two of them the view passes through the up direction:
    /// the interpolated camera keeps a finite basis, rolled from the earlier keyframe's.
    #[test]
    fn a_path_looking_through_up_keeps_a_finite_camera() {
        let p = CameraPath::from_json(
            r#"{"keyframes": [{"frame": 0, "eye": [0.278,0.273,-0.8], "target": [1.278,0.273,-0.8], "fov": 40},
                              {"frame": 2, "eye": [0.278,0.273,-0.8], "target": [-0.722,2.273,-0.8], "fov": 40}]}"#,
        )
        .unwrap();
        let c = p.at(1.0);
        assert!(c.is_finite(), "{c:?}");
        assert!((c.forward - Vec3::Y).length() < 1e-5, "{c:?}");
        assert!(c.right.dot(c.forward).abs() < 1e-5 && c.up.dot(c.forward).abs() < 1e-5 && (c.right.length() - 1.0).abs() < 1e-5);
        // The earlier keyframe's right axis (forward +x × up +y = +z) is kept.
        assert!((c.right - Vec3::Z).length() < 1e-5, "{c:?}");
    }

    /// Eye and target 1e-7 apart at coordinates of 1: the interpolated points rounded to one
    /// point at frame 1 and the camera panicked; the interpolated view direction does not round.
    #[test]
    fn a_path_with_eye_and_target_close_together_interpolates() {
        let p = CameraPath::from_json(
            r#"{"keyframes": [{"frame": 0, "eye": [1,0,0], "target": [1.0000001,0,0], "fov": 40},
                              {"frame": 2, "eye": [3,0,0], "target": [2.9999998,0,0], "fov": 40}]}"#,
        )
        .unwrap();
        for f in [0.0, 0.5, 1.0, 1.5, 2.0] {
            let c = p.at(f);
            assert!(c.is_finite() && (c.forward.length() - 1.0).abs() < 1e-5, "frame {f}: {c:?}");
        }
        // The direction turns over where the interpolated one crosses zero (at frame 2/3).
        assert!((p.at(0.5).forward - Vec3::X).length() < 1e-5, "{:?}", p.at(0.5));
        assert!((p.at(1.0).forward + Vec3::X).length() < 1e-5, "{:?}", p.at(1.0));
    }

    /// A scene camera whose yfov --fov would refuse stops a run that looks through it, naming the
    /// file and the way round; one that --eye/--target or --camera-path replace goes on.
    #[test]
    fn a_scene_camera_with_a_bad_yfov_is_refused_unless_replaced() {
        let info = |yfov: Option<f32>| crate::scene_gpu::SceneInfo {
            origin: Vec3::ZERO,
            path: "bad.gltf".into(),
            meshes: 0,
            materials: 0,
            textured_materials: 0,
            bounds: (Vec3::ZERO, Vec3::ONE),
            surface_area: 0.0,
            camera: yfov.map(|y| (glam::Mat4::IDENTITY, y)),
            warnings: Vec::new(),
            files: Vec::new(),
        };
        for bad in [0.0, -0.5, 4.0, f32::NAN] {
            let why = scene_camera_problem(&info(Some(bad)), None, false).expect("refused");
            assert!(why.starts_with("bad.gltf: its camera's yfov") && why.contains("--eye/--target"), "{why}");
            let replaced = CameraOverride { eye: Vec3::Z, target: Vec3::ZERO, up: Vec3::Y, yfov_degrees: 40.0 };
            assert_eq!(scene_camera_problem(&info(Some(bad)), Some(&replaced), false), None);
            assert_eq!(scene_camera_problem(&info(Some(bad)), None, true), None);
        }
        assert_eq!(scene_camera_problem(&info(Some(0.7)), None, false), None);
        assert_eq!(scene_camera_problem(&info(None), None, false), None);
    }

    /// The automatic camera frames bounds whose diagonal overflows f32 (and a scene of one point).
    #[test]
    fn automatic_camera_is_finite_for_extreme_bounds() {
        for (lo, hi) in [(Vec3::splat(-1e19), Vec3::splat(1e19)), (Vec3::splat(-3e38), Vec3::splat(3e38)), (Vec3::ZERO, Vec3::ZERO)] {
            let info = crate::scene_gpu::SceneInfo {
                origin: Vec3::ZERO,
                path: "test".into(),
                meshes: 0,
                materials: 0,
                textured_materials: 0,
                bounds: (lo, hi),
                surface_area: 0.0,
                camera: None,
                warnings: Vec::new(),
                files: Vec::new(),
            };
            let c = Camera::initial(&info, None);
            assert!(c.is_finite() && (c.forward.length() - 1.0).abs() < 1e-5, "{lo} {hi}: {c:?}");
        }
    }

    #[test]
    fn look_at_is_finite_for_degenerate_input() {
        let cases = [
            (Vec3::ZERO, Vec3::ZERO, Vec3::Y),
            (Vec3::ZERO, Vec3::Y, Vec3::Y),
            (Vec3::ZERO, Vec3::X, Vec3::ZERO),
            (Vec3::splat(3e38), Vec3::splat(-3e38), Vec3::Y),
            (Vec3::ZERO, Vec3::new(1e-40, 0.0, 0.0), Vec3::Y),
        ];
        for (eye, target, up) in cases {
            let c = Camera::look_at(eye, target, up, 0.7, "test");
            assert!(c.is_finite() && (c.forward.length() - 1.0).abs() < 1e-5 && (c.up.length() - 1.0).abs() < 1e-5, "{eye} {target} {up}: {c:?}");
        }
    }

    #[test]
    fn saved_camera_round_trips() {
        let c = cam();
        let p = CameraPath::from_json(&CameraPath::still(&c).to_json()).unwrap();
        let back = p.at(0.0);
        assert!((back.position - c.position).length() < 1e-6);
        assert!((back.forward - c.forward).length() < 1e-6);
        assert!((back.yfov - c.yfov).abs() < 1e-6);
    }

    /// Saved far from the origin (a scene in millimetres, a planet), the camera reads back with
    /// its direction: one unit ahead of an eye at 3e7 rounded it by 16°.
    #[test]
    fn a_camera_far_from_the_origin_round_trips() {
        for eye in [Vec3::new(4e4, 1.5e3, 6e4), Vec3::new(3e7, 0.0, 1e7), Vec3::new(-9e17, 2e17, 0.0)] {
            let c = Camera::look_at(eye, eye + Vec3::new(0.3, -0.2, 1.0) * eye.length() * 1e-3, Vec3::Y, 0.7, "test");
            let back = CameraPath::from_json(&CameraPath::still(&c).to_json()).unwrap().at(0.0);
            // The angle, from the cross product (a dot product near 1 cannot resolve it in f32).
            let angle = back.forward.cross(c.forward).length();
            assert!(angle < 2e-5, "eye {eye}: the saved view turned by {angle} rad");
            let o = c.as_override(Vec3::ZERO);
            let angle = (o.target - o.eye).normalize().cross(c.forward).length();
            assert!(angle < 2e-5, "eye {eye}: the override's view turned by {angle} rad");
        }
    }

    /// Whether up is parallel to the view does not depend on its length.
    #[test]
    fn an_up_of_any_length_is_judged_by_its_direction() {
        let (eye, target) = (Vec3::ZERO, Vec3::Z);
        for scale in [1e-25, 1.0, 1e20, 3e38] {
            assert_eq!(view_problem(eye, target, Vec3::Y * scale), None, "up {scale}");
            assert_eq!(view_problem(eye, target, Vec3::Z * scale), Some(ViewProblem::UpParallel), "up along the view, {scale}");
        }
        assert_eq!(view_problem(eye, target, Vec3::ZERO), Some(ViewProblem::UpParallel));
    }

    /// A path file that starts with a byte-order mark (Windows editors write one) reads.
    #[test]
    fn a_path_with_a_byte_order_mark_reads() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("bom.json");
        std::fs::write(&file, format!("\u{feff}{}", CameraPath::still(&cam()).to_json())).unwrap();
        assert_eq!(CameraPath::load(&file).unwrap().keyframes.len(), 1);
    }

    /// A camera pitched steeply, or looking straight down, in a Y-up scene still yaws about Y and
    /// flies up along it: before, past 60° of pitch the controller took the camera's own up as the
    /// world's, so a yaw rolled the horizon by up to the pitch and Space moved along a tilted axis.
    #[test]
    fn a_steep_camera_yaws_about_the_scenes_up() {
        for pitch in [-30f32, -70.0, -89.9, -90.0, 80.0] {
            let p = pitch.to_radians();
            let eye = Vec3::new(0.0, 2.0, 0.0);
            let c = Camera::look_at(eye, eye + Vec3::new(0.0, p.sin(), -p.cos()), Vec3::Y, 0.7, "test");
            let mut f = FlyController::new(&c, 10.0, Vec3::Y);
            // The camera as given while nothing moved; a tiny look keeps its heading (a view along
            // the axis takes it from the camera's up).
            f.look(1e-3, 0.0);
            let nudged = f.camera();
            assert!(nudged.forward.dot(c.forward) > 0.999 && nudged.up.dot(c.up) > 0.999, "pitch {pitch}: {nudged:?} against {c:?}");
            // A quarter turn: the horizon stays level.
            f.look(std::f32::consts::FRAC_PI_2 / 0.003, 0.0);
            let turned = f.camera();
            assert!(turned.right.dot(Vec3::Y).abs() < 1e-4, "pitch {pitch}: right {} after a yaw", turned.right);
            f.key(MoveKey::Up, true, 0.0);
            f.update(0.5);
            let rise = f.camera().position - eye;
            assert!(rise.normalize().dot(Vec3::Y) > 0.9999, "pitch {pitch}: Space moved along {rise}");
        }
        // Straight down, the image's top edge towards +X: a tiny look keeps that heading (the
        // view has no horizontal part to take it from).
        let c = Camera::look_at(Vec3::ZERO, Vec3::NEG_Y, Vec3::X, 0.7, "test");
        let mut f = FlyController::new(&c, 10.0, Vec3::Y);
        f.look(1e-3, 0.0);
        assert!(f.camera().up.dot(Vec3::X) > 0.999 && f.camera().forward.dot(Vec3::NEG_Y) > 0.999, "{:?}", f.camera());
        // A Z-up scene (--up 0,0,1) flies about Z: a steep view, and a level one along +Y
        // (Blender's front view), which a rule guessing the axis from the camera took for a Y-up
        // camera pitched 90°.
        for target in [Vec3::new(1.0, 0.0, -3.0), Vec3::new(0.0, 5.0, 0.0)] {
            let c = Camera::look_at(Vec3::ZERO, target, Vec3::Z, 0.7, "test");
            let mut f = FlyController::new(&c, 10.0, Vec3::Z);
            f.look(1e-3, 0.0);
            assert!(f.camera().forward.dot(c.forward) > 0.999 && f.camera().up.dot(c.up) > 0.999, "{target}: {:?}", f.camera());
            f.look(300.0, 0.0);
            assert!(f.camera().right.dot(Vec3::Z).abs() < 1e-4, "{target}: {:?}", f.camera());
        }
    }

    #[test]
    fn controller_returns_the_given_camera_until_it_moves() {
        let c = cam();
        let mut f = FlyController::new(&c, 10.0, Vec3::Y);
        assert!(f.camera().same_view(&c));
        assert!(!f.update(0.1), "no key held: no move");
        f.key(MoveKey::Forward, true, 0.1);
        assert!(f.update(0.6));
        let moved = f.camera();
        // speed 0.2 × 10 = 2 units/s for 0.5 s along -z.
        assert!((moved.position - Vec3::new(0.0, 1.0, 4.0)).length() < 1e-4, "{:?}", moved.position);
        assert!((moved.forward - c.forward).length() < 1e-5);
        f.key(MoveKey::Forward, false, 0.6);
        f.set_fast(true);
        f.key(MoveKey::Right, true, 1.0);
        f.update(1.5);
        assert!((f.camera().position - Vec3::new(6.0, 1.0, 4.0)).length() < 1e-3);
        f.key(MoveKey::Right, false, 1.5);
        f.set_fast(false);
        f.go_home();
        assert!(f.camera().same_view(&c));
    }

    #[test]
    fn release_all_stops_the_camera_after_what_was_held() {
        let c = cam();
        let mut f = FlyController::new(&c, 10.0, Vec3::Y);
        f.update(0.0);
        f.set_fast(true);
        f.key(MoveKey::Forward, true, 0.0);
        f.key(MoveKey::Up, true, 0.0);
        f.release_all(0.25);
        assert!(f.update(0.5), "what was held until the release moves");
        let after = f.camera().position;
        assert!(!f.update(2.0), "nothing held afterwards");
        assert_eq!(f.camera().position, after);
        // Fast was released too: 0.25 s forward at 2 units/s is 0.5, not 3.
        f.key(MoveKey::Forward, true, 2.0);
        f.update(2.25);
        assert!(((f.camera().position - after).length() - 0.5).abs() < 1e-3, "{:?}", f.camera().position - after);
    }

    #[test]
    fn a_tap_between_two_slow_frames_moves_by_what_was_held() {
        let c = cam();
        let mut f = FlyController::new(&c, 10.0, Vec3::Y);
        f.update(0.0);
        // W down for 0.3 s, released, all within one 2-second frame; a repeat press is ignored.
        f.key(MoveKey::Forward, true, 0.5);
        f.key(MoveKey::Forward, true, 0.6);
        f.key(MoveKey::Forward, false, 0.8);
        assert!(f.update(2.0), "the tap moved the camera");
        assert!(
            (f.camera().position - Vec3::new(0.0, 1.0, 4.4)).length() < 1e-4,
            "{:?}",
            f.camera().position
        );
        assert!(!f.update(3.0), "released: no further move");
        // Pressed and released at the same moment (read between two slow frames): a nudge.
        f.key(MoveKey::Forward, true, 3.0);
        f.key(MoveKey::Forward, false, 3.0);
        f.update(3.0);
        let nudge = 4.4 - f.camera().position.z;
        assert!(
            (nudge - 2.0 * FlyController::MIN_TAP_SECONDS as f32).abs() < 1e-4,
            "{nudge}"
        );
        f.set_camera(&Camera::look_at(
            Vec3::new(0.0, 1.0, 4.4),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::Y,
            0.7,
            "test",
        ));
        // A stall (no update for 10 s with the key down) moves at most MAX_STEP_SECONDS.
        f.key(MoveKey::Back, true, 3.0);
        f.update(13.0);
        let moved = f.camera().position.z - 4.4;
        assert!(
            (moved - 2.0 * FlyController::MAX_STEP_SECONDS as f32).abs() < 1e-4,
            "{moved}"
        );
    }

    #[test]
    fn controller_looks_and_clamps_pitch() {
        let mut f = FlyController::new(&cam(), 10.0, Vec3::Y);
        // Turning right by a quarter turn: forward goes from -z to +x.
        f.look(std::f32::consts::FRAC_PI_2 / f.sensitivity, 0.0);
        assert!((f.camera().forward - Vec3::X).length() < 1e-4, "{:?}", f.camera().forward);
        f.look(0.0, -1e6);
        assert!(f.camera().forward.y < 1.0 && f.camera().forward.y > 0.99, "pitch clamped below 90°");
        f.scroll(1.0);
        assert!((f.speed - 2.5).abs() < 1e-5);
    }
}
