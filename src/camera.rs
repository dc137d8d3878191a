//! The camera: where a frame is seen from. The renderer takes one per frame; headless runs, camera
//! paths and the window's controller decide which.

use glam::{Mat4, Vec3};
use serde::Serialize;

use crate::scene_gpu::SceneInfo;
use crate::settings::CameraOverride;

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
        let forward = (-t.z_axis.truncate()).normalize();
        let up0 = t.y_axis.truncate();
        let right = forward.cross(up0).normalize();
        let up = right.cross(forward);
        Self { position: t.w_axis.truncate(), forward, right, up, yfov, source }
    }

    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, yfov: f32, source: &'static str) -> Self {
        let forward = (target - eye).normalize();
        let right = forward.cross(up).normalize();
        let up = right.cross(forward);
        Self { position: eye, forward, right, up, yfov, source }
    }

    /// The camera a run starts from: the command line's, else the scene's, else one that frames the
    /// scene's bounds from +z.
    pub fn initial(scene: &SceneInfo, camera: Option<&CameraOverride>) -> Self {
        if let Some(c) = camera {
            return Self::look_at(c.eye, c.target, c.up, c.yfov_degrees.to_radians(), "command line");
        }
        if let Some((transform, yfov)) = scene.camera {
            return Self::from_transform(transform, yfov, "scene camera");
        }
        let (lo, hi) = scene.bounds;
        let centre = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(1e-3);
        let yfov = 45f32.to_radians();
        let distance = radius / (yfov * 0.5).tan() * 1.1;
        Self::look_at(centre + Vec3::Z * distance, centre, Vec3::Y, yfov, "automatic (no camera in the scene)")
    }

    /// Whether two cameras see the same image (position, orientation and field of view; the
    /// source does not count).
    pub fn same_view(&self, other: &Camera) -> bool {
        self.position == other.position && self.forward == other.forward && self.up == other.up && self.yfov == other.yfov
    }
}
