//! A pass's pipeline builder refuses what its desc does not describe, before any pipeline is
//! made: a specialisation constant left unset, set twice or unknown, and a shader variant the pass
//! does not have. (The passes' own constructors set everything; these are the errors a new pass
//! or a changed desc would meet.)

mod common;

use ash::vk;
use gpu_allocator::MemoryLocation;
use restir_vpl::passes::desc::PipelineBuilder;
use restir_vpl::passes::{RestirSpatialPass, RestirTemporalPass};
use restir_vpl::vk::{Buffer, DescriptorSet};

/// `b` with bindings 0 … n − 1 all bound to `buffer`.
fn bind_all<'a>(b: PipelineBuilder<'a>, buffer: &'a Buffer, n: u32) -> PipelineBuilder<'a> {
    let pairs: Vec<(u32, &Buffer)> = (0..n).map(|i| (i, buffer)).collect();
    b.buffers(&pairs)
}

#[test]
fn the_builder_refuses_what_the_desc_lacks() {
    let ctx = common::context();
    let empty = DescriptorSet::new(&ctx, "test.set0", &[]).unwrap();
    let dummy = Buffer::new(&ctx, "test.dummy", 256, vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::GpuOnly).unwrap();
    let error = |r: anyhow::Result<restir_vpl::vk::ComputePipeline>| match r {
        Ok(_) => panic!("the builder accepted it"),
        Err(e) => format!("{e:#}"),
    };
    // Every binding bound, so that only the constants and the variant are wrong.
    let spatial = |b| bind_all(b, &dummy, 5);
    let desc = &RestirSpatialPass::DESC;

    let e = error(spatial(desc.pipeline(&ctx, empty.layout)).build());
    assert!(e.contains("specialisation constant 2 ('UNBIASED') is set 0 times"), "{e}");
    let e = error(spatial(desc.pipeline(&ctx, empty.layout)).constant("UNBIASED", 1).constant("UNBIASED", 0).constant("VISIBLE_TARGETS", 0).build());
    assert!(e.contains("specialisation constant 2 ('UNBIASED') is set 2 times"), "{e}");
    let e = error(spatial(desc.pipeline(&ctx, empty.layout)).constant("UNBIASED", 1).constant("VISIBLE", 0).build());
    assert!(e.contains("no specialisation constant [\"VISIBLE\"]"), "{e}");
    let e = error(spatial(desc.pipeline(&ctx, empty.layout)).constant("UNBIASED", 1).constant("VISIBLE_TARGETS", 0).grid(true).build());
    assert!(e.contains("restir_spatial' has no grid variant"), "{e}");
    let e = error(spatial(desc.pipeline(&ctx, empty.layout)).constant("UNBIASED", 1).constant("VISIBLE_TARGETS", 0).textured(true).build());
    assert!(e.contains("has no textured variant"), "{e}");
    // A pass without constants takes none.
    let temporal = RestirTemporalPass::DESC.pipeline(&ctx, empty.layout).constant("UNBIASED", 1);
    let e = error(bind_all(temporal, &dummy, 5).build());
    assert!(e.contains("restir_temporal' declares no specialisation constant [\"UNBIASED\"] (it has [])"), "{e}");
    // Refused before anything reached the driver: nothing the layer could report.
    common::assert_no_validation_errors(&ctx);
}
