//! The evaluation harness, apart from the renderer: long references and their merging
//! ([`reference`]), image metrics ([`compare`]), benchmarks ([`bench`]), the error-versus-time study
//! ([`results`]) and the Markdown/CSV/plot report it writes ([`report`]). Everything here drives the
//! renderer through [`crate::renderer::Renderer`] like any other caller.

pub mod bench;
pub mod compare;
pub mod motion;
pub mod radius;
pub mod rays;
pub mod reference;
pub mod report;
pub mod results;
pub mod scaling;
