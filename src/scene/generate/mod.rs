//! Scene generators: the glTF files in `scenes/` (written by code and checked byte for byte by the
//! scene tests) and the analytic test scenes (furnace box), built with [`GltfBuilder`].

pub mod builder;
pub mod cornell;
pub mod thesis;

pub use builder::{closed_box, orient_quad, GltfBuilder};
pub use cornell::{cornell_box_gltf, furnace_box_gltf};
pub use thesis::{living_room_gltf, open_box_figure_gltf};
