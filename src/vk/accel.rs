//! Acceleration structures, built once: one BLAS per mesh, one TLAS over the instances.

use std::sync::Arc;

use anyhow::{Context as _, Result};
use ash::vk;
use gpu_allocator::MemoryLocation;

use super::{leaf_order, Buffer, Context};

pub struct AccelerationStructure {
    ctx: Arc<Context>,
    pub raw: vk::AccelerationStructureKHR,
    pub buffer: Buffer,
    pub address: vk::DeviceAddress,
}

impl Drop for AccelerationStructure {
    fn drop(&mut self) {
        if self.ctx.is_hung() {
            return; // a submission that did not finish may still use it (Context::wait_fence)
        }
        // SAFETY: no pending GPU work references the structure (frames are fenced).
        unsafe { self.ctx.accel.destroy_acceleration_structure(self.raw, None) };
    }
}

/// A mesh's range in the global vertex/index buffers.
#[derive(Clone, Copy, Debug)]
pub struct MeshRange {
    pub first_vertex: u32,
    pub vertex_count: u32,
    pub first_index: u32,
    pub index_count: u32,
}

fn align_up(x: u64, a: u64) -> u64 {
    x.div_ceil(a.max(1)) * a.max(1)
}

fn build(
    ctx: &Arc<Context>,
    name: &str,
    ty: vk::AccelerationStructureTypeKHR,
    geometry: vk::AccelerationStructureGeometryKHR<'_>,
    primitive_count: u32,
) -> Result<AccelerationStructure> {
    let geometries = [geometry];
    let mut build_info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
        .ty(ty)
        .flags(vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE)
        .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
        .geometries(&geometries);
    let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
    // SAFETY: build_info references live geometry data.
    unsafe {
        ctx.accel.get_acceleration_structure_build_sizes(
            vk::AccelerationStructureBuildTypeKHR::DEVICE,
            &build_info,
            &[primitive_count],
            &mut sizes,
        )
    };
    let buffer = Buffer::new(
        ctx,
        name,
        sizes.acceleration_structure_size,
        vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
        MemoryLocation::GpuOnly,
    )?;
    let create = vk::AccelerationStructureCreateInfoKHR::default()
        .buffer(buffer.raw)
        .size(sizes.acceleration_structure_size)
        .ty(ty);
    // SAFETY: the backing buffer is large enough (queried above).
    let raw = unsafe { ctx.accel.create_acceleration_structure(&create, None) }
        .with_context(|| format!("vkCreateAccelerationStructureKHR '{name}'"))?;
    ctx.set_name(raw, name);
    // Owned from here on, so that a failure below destroys it.
    let mut accel = AccelerationStructure { ctx: ctx.clone(), raw, buffer, address: 0 };
    let align = ctx.as_properties.min_scratch_offset_alignment as u64;
    let scratch = Buffer::new(
        ctx,
        &format!("{name}.scratch"),
        sizes.build_scratch_size + align,
        vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
        MemoryLocation::GpuOnly,
    )?;
    build_info = build_info
        .dst_acceleration_structure(raw)
        .scratch_data(vk::DeviceOrHostAddressKHR { device_address: align_up(scratch.address(), align) });
    let range = [vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(primitive_count)];
    let ranges: [&[vk::AccelerationStructureBuildRangeInfoKHR]; 1] = [&range];
    ctx.one_shot(|cmd| {
        ctx.begin_label(cmd, name);
        // SAFETY: inputs and scratch stay alive until one_shot's wait returns.
        unsafe { ctx.accel.cmd_build_acceleration_structures(cmd, std::slice::from_ref(&build_info), &ranges) };
        ctx.end_label(cmd);
    })?;
    // SAFETY: raw is a valid acceleration structure.
    accel.address = unsafe {
        ctx.accel.get_acceleration_structure_device_address(
            &vk::AccelerationStructureDeviceAddressInfoKHR::default().acceleration_structure(raw),
        )
    };
    Ok(accel)
}

/// One instance of a mesh in the scene.
#[derive(Clone, Copy, Debug)]
pub struct InstanceDesc {
    pub mesh: usize,
    /// Row-major 3×4 world-from-object transform.
    pub transform: [f32; 12],
}

/// The scene's acceleration structures.
pub struct SceneAccel {
    pub tlas: AccelerationStructure,
    /// BLASes built (one per mesh some instance uses).
    pub blas_count: usize,
    /// Wall ms of the BLAS builds and of the TLAS build (each waits for its submission).
    pub blas_ms: f64,
    pub tlas_ms: f64,
    // Kept alive for the TLAS.
    _blases: Vec<AccelerationStructure>,
    _tlas_instances: Buffer,
}

/// A scene of at most this many triangles has its instances merged into one world-space mesh
/// before the BLASes are built (`Scene::merged`, `--merge-blas`): one BVH, no instance transforms.
/// On lavapipe that made the Cornell box's (32 triangles) photon pass 0.8× as long; it made the
/// living room's (13,556) and the open box's (76,662) camera passes slower, since the driver's
/// equal-count splits then mix the room's large walls with the furniture. See docs/performance.md,
/// "Acceleration structures on lavapipe".
pub const MERGE_MAX_TRIANGLES: u32 = 1024;

fn triangles<'a>(
    vertices: &Buffer,
    vertex_stride: u64,
    indices: &Buffer,
    m: &MeshRange,
) -> vk::AccelerationStructureGeometryKHR<'a> {
    let triangles = vk::AccelerationStructureGeometryTrianglesDataKHR::default()
        .vertex_format(vk::Format::R32G32B32_SFLOAT)
        .vertex_data(vk::DeviceOrHostAddressConstKHR {
            device_address: vertices.address() + m.first_vertex as u64 * vertex_stride,
        })
        .vertex_stride(vertex_stride)
        .max_vertex(m.vertex_count.saturating_sub(1))
        .index_type(vk::IndexType::UINT32)
        .index_data(vk::DeviceOrHostAddressConstKHR { device_address: indices.address() + m.first_index as u64 * 4 });
    vk::AccelerationStructureGeometryKHR::default()
        .geometry_type(vk::GeometryTypeKHR::TRIANGLES)
        .geometry(vk::AccelerationStructureGeometryDataKHR { triangles })
        .flags(vk::GeometryFlagsKHR::OPAQUE)
}

/// Builds one BLAS per mesh that an instance uses, over the global vertex buffer (`GpuVertex`,
/// position first) and index buffer (indices local to each mesh), and the TLAS over the instances;
/// instance i has `instanceCustomIndex` i. The instances are handed to the TLAS build in
/// [`leaf_order::midpoint_split_order`] of their world bounds `instance_bounds` (the order only
/// matters to a driver that does not sort, as lavapipe; see there).
pub fn build_scene(
    ctx: &Arc<Context>,
    vertices: &Buffer,
    vertex_stride: u64,
    indices: &Buffer,
    meshes: &[(String, MeshRange)],
    instances: &[InstanceDesc],
    instance_bounds: &[leaf_order::Aabb],
) -> Result<SceneAccel> {
    let blas_start = std::time::Instant::now();
    let mut blases = Vec::new();
    let mut mesh_blas: Vec<Option<usize>> = vec![None; meshes.len()];
    for inst in instances {
        if mesh_blas[inst.mesh].is_none() {
            let (name, m) = &meshes[inst.mesh];
            let geometry = triangles(vertices, vertex_stride, indices, m);
            blases.push(
                build(ctx, &format!("blas.{name}"), vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL, geometry, m.index_count / 3)
                    .with_context(|| format!("building the BLAS of mesh '{name}'"))?,
            );
            mesh_blas[inst.mesh] = Some(blases.len() - 1);
        }
    }
    let blas_ms = blas_start.elapsed().as_secs_f64() * 1e3;
    let tlas_start = std::time::Instant::now();
    let tlas_instances: Vec<(usize, u32, [f32; 12])> = leaf_order::midpoint_split_order(instance_bounds)
        .into_iter()
        .map(|i| {
            let inst = &instances[i as usize];
            (mesh_blas[inst.mesh].expect("every instance's mesh has a BLAS (built above)"), i, inst.transform)
        })
        .collect();
    let (tlas, tlas_buffer) = build_tlas(ctx, &blases, &tlas_instances).context("building the TLAS")?;
    Ok(SceneAccel {
        tlas,
        blas_count: blases.len(),
        blas_ms,
        tlas_ms: tlas_start.elapsed().as_secs_f64() * 1e3,
        _blases: blases,
        _tlas_instances: tlas_buffer,
    })
}

/// The most instances a TLAS of this renderer holds: the device's maxInstanceCount, and 2^24,
/// since an instance's custom index (the shaders' instance record) is 24 bits (past it
/// `Packed24_8` cut the index, and hits read another instance's record).
pub fn check_instance_count(instances: usize, max_instance_count: u64) -> Result<()> {
    let most = max_instance_count.min(1 << 24);
    anyhow::ensure!(
        instances as u64 <= most,
        "the scene has {instances} instances (after merging), more than a TLAS here holds ({most}: the device's \
         maxInstanceCount {max_instance_count} and the 24-bit custom index); merge meshes in the scene"
    );
    Ok(())
}

/// Builds the TLAS over (BLAS, custom index, row-major 3×4 transform) instances.
fn build_tlas(
    ctx: &Arc<Context>,
    blases: &[AccelerationStructure],
    instances: &[(usize, u32, [f32; 12])],
) -> Result<(AccelerationStructure, Buffer)> {
    check_instance_count(instances.len(), ctx.as_properties.max_instance_count)?;
    let raw: Vec<vk::AccelerationStructureInstanceKHR> = instances
        .iter()
        .map(|&(blas, custom_index, transform)| vk::AccelerationStructureInstanceKHR {
            transform: vk::TransformMatrixKHR { matrix: transform },
            instance_custom_index_and_mask: vk::Packed24_8::new(custom_index, 0xff),
            instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(
                0,
                vk::GeometryInstanceFlagsKHR::TRIANGLE_FACING_CULL_DISABLE.as_raw() as u8,
            ),
            acceleration_structure_reference: vk::AccelerationStructureReferenceKHR {
                device_handle: blases[blas].address,
            },
        })
        .collect();
    // SAFETY: AccelerationStructureInstanceKHR is a plain 64-byte C struct.
    let bytes = unsafe {
        std::slice::from_raw_parts(raw.as_ptr() as *const u8, std::mem::size_of_val(raw.as_slice()))
    };
    let instance_buffer = Buffer::with_data(
        ctx,
        "tlas.instances",
        bytes,
        vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
    )?;
    // The build reads instances at a 16-byte aligned address (VUID-vkCmdBuildAccelerationStructuresKHR
    // -pInfos-03715), which a buffer's memory alignment gives on every driver seen but the spec
    // does not promise.
    anyhow::ensure!(
        instance_buffer.address() % 16 == 0,
        "tlas.instances: the driver placed the instance buffer at {:#x}, not 16-byte aligned as the TLAS build needs",
        instance_buffer.address()
    );
    let data = vk::AccelerationStructureGeometryInstancesDataKHR::default()
        .array_of_pointers(false)
        .data(vk::DeviceOrHostAddressConstKHR { device_address: instance_buffer.address() });
    let geometry = vk::AccelerationStructureGeometryKHR::default()
        .geometry_type(vk::GeometryTypeKHR::INSTANCES)
        .geometry(vk::AccelerationStructureGeometryDataKHR { instances: data })
        .flags(vk::GeometryFlagsKHR::OPAQUE);
    let tlas = build(ctx, "tlas", vk::AccelerationStructureTypeKHR::TOP_LEVEL, geometry, instances.len() as u32)?;
    Ok((tlas, instance_buffer))
}

#[cfg(test)]
mod tests {
    /// A TLAS holds at most the device's maxInstanceCount instances, and 2^24 whatever the device
    /// says (the custom index is 24 bits); the error names both.
    #[test]
    fn instance_counts_past_the_custom_index_are_refused() {
        assert!(super::check_instance_count(1 << 24, u64::MAX).is_ok());
        let e = super::check_instance_count((1 << 24) + 1, u64::MAX).unwrap_err().to_string();
        assert!(e.contains("16777217 instances") && e.contains("(16777216:"), "{e}");
        assert!(super::check_instance_count(1000, 999).unwrap_err().to_string().contains("maxInstanceCount 999"));
    }
}
