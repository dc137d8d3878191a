//! The surface-area cost of the tree lavapipe builds over each bundled scene's triangles (all
//! instances merged into one world-space mesh), in the file's order and in
//! `leaf_order::midpoint_split_order`, and the time that order takes on the host.
//!
//! `cargo run --release --example bvh_order`
//!
//! The cost is `leaf_order::lavapipe_tree_cost` over the root's half area: Σ over the internal
//! nodes of the tree lavapipe builds (`lvp_acceleration_structure.c` splits the array it is given
//! at its middle index, recursively) of their half surface area, the expected number of nodes a
//! ray through the scene's box visits, up to a constant (the measure a SAH builder minimises).

use restir_vpl::vk::leaf_order::{lavapipe_tree_cost, midpoint_split_order, Aabb};

fn main() -> anyhow::Result<()> {
    println!("| scene | triangles | cost, file order | cost, midpoint_split_order | order time |");
    println!("|---|---:|---:|---:|---:|");
    for name in ["cornell_box", "living_room", "open_box_figure"] {
        let scene = restir_vpl::scene::Scene::load(std::path::Path::new(&format!("scenes/{name}.gltf")))?;
        let merged = scene.merged();
        let mesh = merged.meshes.last().expect("merged() appends the merged mesh");
        let bounds: Vec<Aabb> = (0..mesh.triangle_count())
            .map(|t| mesh.triangle(t).map_or(Aabb::EMPTY, |p| Aabb::of_points(&p)))
            .collect();
        let root = bounds.iter().fold(Aabb::EMPTY, |a, b| a.grow(*b)).half_area() as f64;
        let file_order: Vec<u32> = (0..bounds.len() as u32).collect();
        let start = std::time::Instant::now();
        let ordered = midpoint_split_order(&bounds);
        let ms = start.elapsed().as_secs_f64() * 1e3;
        println!(
            "| {name} | {} | {:.1} | {:.1} | {ms:.1} ms |",
            bounds.len(),
            lavapipe_tree_cost(&bounds, &file_order) / root,
            lavapipe_tree_cost(&bounds, &ordered) / root
        );
    }
    Ok(())
}
