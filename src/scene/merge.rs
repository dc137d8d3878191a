//! Merging every instance into one world-space mesh, for the acceleration structures
//! (`SceneGpu::new`, `--merge-blas`).

use glam::{Mat3, Mat4, Vec3};

use super::{Instance, Mesh, Scene};

impl Scene {
    /// The scene with every instance baked into one world-space mesh (`merged`, appended to the
    /// meshes) under one identity instance, which replaces them all. Positions are transformed with
    /// the instance's matrix, normals with its inverse transpose, and a mirroring instance's
    /// triangles have their winding reversed so that their front face stays the glTF one; materials
    /// and texture coordinates follow their triangles. Memory grows with the instanced triangle
    /// count (an instanced mesh is copied once per instance).
    pub fn merged(&self) -> Scene {
        let mut merged = Mesh { name: "merged".into(), ..Mesh::default() };
        for inst in &self.instances {
            let Some(mesh) = self.meshes.get(inst.mesh) else { continue };
            let t: Mat4 = inst.transform;
            let linear = Mat3::from_mat4(t);
            let normal_matrix = linear.inverse().transpose();
            // In f32 the determinant of a scale beyond ~7e12 overflows (the inverse is then zero)
            // and one below ~1e-13 underflows (Inf): such instances take f64 and unit normals.
            let normal_matrix_f64 = (!(linear.determinant().is_normal() && normal_matrix.is_finite()))
                .then(|| linear.as_dmat3().inverse().transpose());
            let base = merged.positions.len() as u32;
            merged.positions.extend(mesh.positions.iter().map(|&p| t.transform_point3(p)));
            merged.normals.extend(mesh.normals.iter().map(|&n| {
                // A missing normal (zero) stays zero: the renderer then uses the flat normal.
                match normal_matrix_f64 {
                    _ if n == Vec3::ZERO => n,
                    None => normal_matrix * n,
                    Some(m) => (m * n.as_dvec3()).normalize_or_zero().as_vec3(),
                }
            }));
            merged.normals.resize(merged.positions.len(), Vec3::ZERO);
            merged.uvs.extend_from_slice(&mesh.uvs);
            merged.uvs.resize(merged.positions.len(), Default::default());
            let mirrored = inst.is_mirrored();
            for tri in mesh.indices.chunks_exact(3) {
                let [a, b, c] = [tri[0] + base, tri[1] + base, tri[2] + base];
                merged.indices.extend_from_slice(&if mirrored { [a, c, b] } else { [a, b, c] });
            }
            merged.triangle_materials.extend_from_slice(&mesh.triangle_materials);
        }
        let mut out = self.clone();
        out.instances = vec![Instance { name: "merged".into(), mesh: self.meshes.len(), transform: Mat4::IDENTITY }];
        out.meshes.push(merged);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(name: &str) -> Mesh {
        Mesh {
            name: name.into(),
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)],
            normals: vec![Vec3::Z; 4],
            uvs: vec![Default::default(); 4],
            indices: vec![0, 1, 2, 2, 1, 3],
            triangle_materials: vec![0, 1],
        }
    }

    fn scene(meshes: Vec<Mesh>, instances: Vec<(usize, Mat4)>) -> Scene {
        Scene {
            path: "test".into(),
            origin: Vec3::ZERO,
            meshes,
            instances: instances
                .into_iter()
                .enumerate()
                .map(|(i, (mesh, transform))| Instance { name: format!("node{i}"), mesh, transform })
                .collect(),
            materials: vec![
                crate::scene::Material::default_material(),
                crate::scene::Material { emission: Vec3::ONE, ..crate::scene::Material::default_material() },
            ],
            camera: None,
            point_lights: vec![],
            textures: vec![],
            warnings: vec![],
            files: vec![],
        }
    }

    /// World-space triangles with their geometric normal (winding order) and material.
    fn world_triangles(s: &Scene) -> Vec<([Vec3; 3], Vec3, u32)> {
        let mut out = Vec::new();
        for inst in &s.instances {
            let mesh = &s.meshes[inst.mesh];
            for t in 0..mesh.triangle_count() {
                let p = mesh.triangle(t).unwrap().map(|v| inst.transform.transform_point3(v));
                let mut n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
                if inst.is_mirrored() {
                    n = -n; // what the renderer does for a mirroring instance (INSTANCE_MIRRORED)
                }
                out.push((p, n, mesh.triangle_materials[t]));
            }
        }
        out
    }

    #[test]
    fn merging_keeps_every_world_triangle_its_facing_and_material() {
        let s = scene(
            vec![quad("a"), quad("b")],
            vec![
                (0, Mat4::from_translation(Vec3::new(0.0, 0.0, 5.0))),
                (1, Mat4::IDENTITY),
                (0, Mat4::from_scale(Vec3::new(-2.0, 1.0, 1.0))), // mirrors
                (0, Mat4::from_rotation_x(1.0)),
            ],
        );
        let m = s.merged();
        assert_eq!((m.instances.len(), m.meshes.len()), (1, 3));
        assert_eq!(m.instances[0].transform, Mat4::IDENTITY);
        assert_eq!(m.triangle_count(), s.triangle_count());
        let (before, after) = (world_triangles(&s), world_triangles(&m));
        assert_eq!(before.len(), after.len());
        for ((p, n, mat), (q, k, mat2)) in before.iter().zip(&after) {
            // The same triangle (up to the winding swap), the same facing, the same material.
            assert!(p[0].abs_diff_eq(q[0], 1e-6), "{p:?} vs {q:?}");
            assert!(p[1].abs_diff_eq(q[1], 1e-6) || p[1].abs_diff_eq(q[2], 1e-6), "{p:?} vs {q:?}");
            assert!(n.abs_diff_eq(*k, 1e-5), "normal {n} vs {k}");
            assert_eq!(mat, mat2);
        }
        // Shading normals follow the inverse transpose: the mirrored quad's +z stays +z, the
        // rotated one's turns with it.
        let merged = &m.meshes[2];
        assert!(merged.normals[8].abs_diff_eq(Vec3::Z, 1e-6));
        assert!(merged.normals[12].normalize().abs_diff_eq(Mat3::from_rotation_x(1.0) * Vec3::Z, 1e-6));
        assert_eq!(merged.normals.len(), merged.positions.len());
        assert_eq!(merged.uvs.len(), merged.positions.len());
        // The emitters (the light set) are the same triangles with the same normals.
        let (e, f) = (s.emissive_triangles(), m.emissive_triangles());
        assert_eq!(e.len(), 4);
        assert_eq!(e.len(), f.len());
        for (a, b) in e.iter().zip(&f) {
            assert!(a.normal.abs_diff_eq(b.normal, 1e-5) && (a.area - b.area).abs() < 1e-5, "{a:?} vs {b:?}");
        }
    }
}
