//! Rust and GLSL agree on every fact they share: the GPU structs, each pass's interface, and the
//! constants of shaders/common/types.glsl.
//!
//! - Structs: `shaders/tests/layout.comp` declares one buffer per struct of
//!   `shaders/common/types.glsl`; glslang assigns std430 (and, for `Frame`, std140) offsets. We read
//!   them back from the SPIR-V (OpMemberName + OpMemberDecorate Offset, OpDecorate ArrayStride of
//!   the runtime arrays) and compare them with `GpuStruct::FIELDS` (generated from the Rust fields
//!   by `offset_of!`).
//! - Passes: for every `PassDesc` (`passes::ALL_PASSES`) and every SPIR-V variant of it, the set-1
//!   bindings, the push-constant block and the local size in the SPIR-V equal the desc's; set 0
//!   equals the scene's table (`SCENE_BINDINGS`, or `SCENE_BINDINGS_TEXTURED` for `textured` variants;
//!   the TLAS only where the pass traces). A `raygen` variant is a ray-generation shader, without a
//!   local size; every pass that traces has one, and no other pass declares a ray-tracing
//!   capability (a device with ray-tracing pipelines only would refuse the module).
//! - Constants: every `const uint` of the header has a Rust twin of the same name and value
//!   (`passes::glsl_constants()`), and every Rust one is in the header.
//!
//! The pass and constant checks return their mismatches, so the negative tests can feed them
//! deliberately drifted descs and headers.

use std::collections::{BTreeMap, HashMap};

use rspirv::dr::{Instruction, Operand};
use rspirv::spirv::{Capability, Decoration, Dim, ExecutionMode, ExecutionModel, Op, StorageClass};

use restir_vpl::gpu_types::*;
use restir_vpl::passes::desc::{PassDesc, PushLayout};
use restir_vpl::passes::{self, AccumulatePass, GbufferPass, RestirSpatialPass, RestirTemporalPass, TonemapPass, VplShadePass};
use restir_vpl::scene_gpu::{SCENE_BINDINGS, SCENE_BINDINGS_TEXTURED};
use restir_vpl::vk::pipeline::{storage, storage_texels, texels, uniform};
use restir_vpl::vk::{Binding, BindingKind};

/// The parts of a SPIR-V module the checks read.
struct Spirv {
    names: HashMap<u32, String>,
    member_names: HashMap<(u32, u32), String>,
    offsets: HashMap<(u32, u32), u32>,
    /// (target, decoration) -> its first literal number (0 for one without, e.g. Block).
    decorations: HashMap<(u32, Decoration), u32>,
    /// Types, constants and global variables, in module order.
    globals: Vec<Instruction>,
    /// Result id -> index in `globals`.
    by_id: HashMap<u32, usize>,
    local_size: Option<[u32; 3]>,
    capabilities: Vec<Capability>,
    execution_models: Vec<ExecutionModel>,
}

fn lit_u32(op: &Operand) -> u32 {
    match op {
        Operand::LiteralBit32(v) => *v,
        Operand::IdRef(v) => *v,
        other => panic!("unexpected operand {other:?}"),
    }
}

/// The first operand of each instruction, where `pick` recognises it (OpCapability's capability,
/// OpEntryPoint's execution model).
fn first_operands<T>(insts: &[Instruction], pick: impl Fn(&Operand) -> Option<T>) -> Vec<T> {
    insts.iter().filter_map(|i| i.operands.first().and_then(&pick)).collect()
}

impl Spirv {
    fn parse(bytes: &[u8]) -> Result<Self, String> {
        let module = rspirv::dr::load_bytes(bytes).map_err(|e| format!("SPIR-V does not parse: {e}"))?;
        let mut s = Spirv {
            names: HashMap::new(),
            member_names: HashMap::new(),
            offsets: HashMap::new(),
            decorations: HashMap::new(),
            globals: module.types_global_values.clone(),
            by_id: HashMap::new(),
            local_size: None,
            capabilities: first_operands(&module.capabilities, |o| match o {
                Operand::Capability(c) => Some(*c),
                _ => None,
            }),
            execution_models: first_operands(&module.entry_points, |o| match o {
                Operand::ExecutionModel(m) => Some(*m),
                _ => None,
            }),
        };
        for inst in &module.debug_names {
            match (inst.class.opcode, inst.operands.as_slice()) {
                (Op::Name, [id, Operand::LiteralString(n)]) => {
                    s.names.insert(lit_u32(id), n.clone());
                }
                (Op::MemberName, [id, m, Operand::LiteralString(n)]) => {
                    s.member_names.insert((lit_u32(id), lit_u32(m)), n.clone());
                }
                _ => {}
            }
        }
        for inst in &module.annotations {
            match (inst.class.opcode, inst.operands.as_slice()) {
                (Op::MemberDecorate, [id, m, Operand::Decoration(Decoration::Offset), off]) => {
                    s.offsets.insert((lit_u32(id), lit_u32(m)), lit_u32(off));
                }
                (Op::Decorate, [id, Operand::Decoration(d), rest @ ..]) => {
                    let literal = match rest.first() {
                        Some(Operand::LiteralBit32(v)) => *v,
                        _ => 0,
                    };
                    s.decorations.insert((lit_u32(id), *d), literal);
                }
                _ => {}
            }
        }
        for inst in &module.execution_modes {
            if let [_, Operand::ExecutionMode(ExecutionMode::LocalSize), x, y, z] = inst.operands.as_slice() {
                s.local_size = Some([lit_u32(x), lit_u32(y), lit_u32(z)]);
            }
        }
        s.by_id = s.globals.iter().enumerate().filter_map(|(i, inst)| Some((inst.result_id?, i))).collect();
        Ok(s)
    }

    fn global(&self, id: u32) -> Result<&Instruction, String> {
        self.by_id.get(&id).map(|&i| &self.globals[i]).ok_or_else(|| format!("no type or constant %{id}"))
    }

    fn member_count(&self, struct_id: u32) -> u32 {
        self.global(struct_id).map(|s| s.operands.len() as u32).unwrap_or(0)
    }

    /// (member names, offsets) of a struct type id.
    fn layout_of(&self, id: u32) -> Vec<(String, u32)> {
        (0..self.member_count(id))
            .map(|m| {
                let name = self.member_names.get(&(id, m)).cloned().unwrap_or_else(|| format!("#{m}"));
                let off = *self.offsets.get(&(id, m)).unwrap_or_else(|| panic!("member {name} has no Offset"));
                (name, off)
            })
            .collect()
    }

    /// The GLSL name of type `id`, as `PushMember::GLSL` writes it: uint, int, float, vecN /
    /// uvecN / ivecN, or a struct's own name.
    fn glsl_type(&self, id: u32) -> String {
        let Ok(t) = self.global(id) else { return format!("%{id}") };
        let ops = &t.operands;
        match t.class.opcode {
            Op::TypeInt if lit_u32(&ops[1]) == 0 => "uint".into(),
            Op::TypeInt => "int".into(),
            Op::TypeFloat => "float".into(),
            Op::TypeVector => {
                let prefix = match self.glsl_type(lit_u32(&ops[0])).as_str() {
                    "float" => "",
                    "uint" => "u",
                    "int" => "i",
                    other => return format!("vector of {other}"),
                };
                format!("{prefix}vec{}", lit_u32(&ops[1]))
            }
            Op::TypeStruct => self.names.get(&id).cloned().unwrap_or_else(|| format!("struct %{id}")),
            other => format!("{other:?}"),
        }
    }

    /// The GLSL type of each member of a struct type id.
    fn member_types(&self, id: u32) -> Vec<String> {
        let Ok(s) = self.global(id) else { return Vec::new() };
        s.operands.iter().map(|o| self.glsl_type(lit_u32(o))).collect()
    }

    /// Bytes a value of type `id` spans in an explicitly laid-out block (scalars, vectors, arrays
    /// and structs: what push-constant blocks hold).
    fn size_of(&self, id: u32) -> Result<u32, String> {
        let t = self.global(id)?;
        let ops = &t.operands;
        match t.class.opcode {
            Op::TypeInt | Op::TypeFloat => Ok(lit_u32(&ops[0]) / 8),
            Op::TypeVector => Ok(lit_u32(&ops[1]) * self.size_of(lit_u32(&ops[0]))?),
            Op::TypeArray => {
                let length = self.global(lit_u32(&ops[1]))?;
                let count = length.operands.first().map(lit_u32).ok_or("array length is not a constant")?;
                let stride = self.decorations.get(&(id, Decoration::ArrayStride)).copied();
                Ok(count * stride.map_or_else(|| self.size_of(lit_u32(&ops[0])), Ok)?)
            }
            Op::TypeStruct => (0..ops.len() as u32).try_fold(0, |end, m| {
                let offset = self.offsets.get(&(id, m)).ok_or_else(|| format!("member {m} of %{id} has no Offset"))?;
                Ok(end.max(offset + self.size_of(lit_u32(&ops[m as usize]))?))
            }),
            other => Err(format!("no size rule for {other:?}")),
        }
    }

    /// Global variables: (variable id, storage class, pointee type id).
    fn variables(&self) -> Vec<(u32, StorageClass, u32)> {
        self.globals
            .iter()
            .filter(|inst| inst.class.opcode == Op::Variable)
            .filter_map(|var| {
                let ptr = self.global(var.result_type?).ok()?;
                match (var.operands.first(), ptr.operands.get(1)) {
                    (Some(Operand::StorageClass(class)), Some(pointee)) => Some((var.result_id?, *class, lit_u32(pointee))),
                    _ => None,
                }
            })
            .collect()
    }
}

/// The struct layout tests read `shaders/tests/layout.comp`.
fn layout_module() -> Spirv {
    Spirv::parse(restir_vpl::shaders::TESTS_LAYOUT).expect("layout.comp SPIR-V parses")
}

/// The std430 struct named `glsl` used as the element of a runtime array: (layout, array stride).
fn std430_struct(r: &Spirv, glsl: &str) -> (Vec<(String, u32)>, u32) {
    let (arr, elem) = r
        .globals
        .iter()
        .filter(|inst| inst.class.opcode == Op::TypeRuntimeArray)
        .map(|inst| (inst.result_id.expect("type id"), lit_u32(&inst.operands[0])))
        .find(|(_, elem)| r.names.get(elem).is_some_and(|n| n == glsl))
        .unwrap_or_else(|| panic!("layout.comp has no runtime array of {glsl}"));
    (r.layout_of(elem), r.decorations[&(arr, Decoration::ArrayStride)])
}

fn check<T: GpuStruct>() {
    let problems = struct_mismatches(T::GLSL_NAME, T::FIELDS, std::mem::size_of::<T>());
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// How the shader's std430 struct `glsl_name` differs from a Rust twin with `fields` (name, byte
/// offset) and `size` bytes: one line per member that differs in name or offset, or is on one side
/// only, and one for the array stride against the size.
fn struct_mismatches(glsl_name: &str, fields: &[(&str, usize)], size: usize) -> Vec<String> {
    let r = layout_module();
    let (glsl, stride) = std430_struct(&r, glsl_name);
    let mut out = Vec::new();
    for i in 0..glsl.len().max(fields.len()) {
        let shader = glsl.get(i).map(|(n, o)| (n.as_str(), *o as usize));
        let rust = fields.get(i).copied();
        if shader != rust {
            let side = |m: Option<(&str, usize)>| m.map_or("absent".to_string(), |(n, o)| format!("'{n}' at {o}"));
            out.push(format!("{glsl_name}: member {i} is {} in the shader, {} in Rust", side(shader), side(rust)));
        }
    }
    if stride as usize != size {
        out.push(format!("{glsl_name}: std430 array stride {stride} in the shader, size {size} in Rust"));
    }
    out
}

#[test]
fn vertex_layout_matches() {
    check::<GpuVertex>();
}

#[test]
fn material_layout_matches() {
    check::<GpuMaterial>();
}

#[test]
fn instance_layout_matches() {
    check::<GpuInstance>();
}

#[test]
fn light_layout_matches() {
    check::<GpuLight>();
}

#[test]
fn alias_entry_layout_matches() {
    check::<GpuAliasEntry>();
}

#[test]
fn surface_layout_matches() {
    check::<GpuSurface>();
}

#[test]
fn vpl_layout_matches() {
    check::<GpuVpl>();
}

#[test]
fn frame_layout_matches_std430_and_std140() {
    check::<GpuFrame>();
    // The frame constants live in a uniform buffer (std140): same offsets required there too.
    let r = layout_module();
    let frame_std140 = r
        .globals
        .iter()
        .filter(|inst| inst.class.opcode == Op::TypeStruct)
        .find(|inst| inst.result_id.and_then(|id| r.names.get(&id)).is_some_and(|n| n == "B7"))
        .map(|block| lit_u32(&block.operands[0]))
        .expect("uniform block B7 found");
    let glsl = r.layout_of(frame_std140);
    let rust: Vec<(String, u32)> = GpuFrame::FIELDS.iter().map(|(n, o)| (n.to_string(), *o as u32)).collect();
    assert_eq!(glsl, rust, "Frame under std140 differs from the Rust layout");
}

/// The check itself can fail: a Rust twin with one member moved, one renamed, one missing or
/// another size is reported, naming the member.
#[test]
fn a_drifted_layout_is_detected() {
    let fields = GpuLight::FIELDS;
    let size = std::mem::size_of::<GpuLight>();
    assert!(struct_mismatches("Light", fields, size).is_empty());
    let moved: Vec<(&str, usize)> = fields.iter().map(|&(n, o)| if n == "area" { (n, o + 4) } else { (n, o) }).collect();
    assert_eq!(struct_mismatches("Light", &moved, size), ["Light: member 1 is 'area' at 12 in the shader, 'area' at 16 in Rust"]);
    let renamed: Vec<(&str, usize)> = fields.iter().map(|&(n, o)| if n == "pdf" { ("probability", o) } else { (n, o) }).collect();
    assert_eq!(struct_mismatches("Light", &renamed, size), ["Light: member 3 is 'pdf' at 28 in the shader, 'probability' at 28 in Rust"]);
    let last = fields.len() - 1;
    assert_eq!(
        struct_mismatches("Light", &fields[..last], size),
        [format!("Light: member {last} is '{}' at {} in the shader, absent in Rust", fields[last].0, fields[last].1)]
    );
    assert_eq!(struct_mismatches("Light", fields, size + 16), [format!("Light: std430 array stride {size} in the shader, size {} in Rust", size + 16)]);
}

#[test]
fn reservoir_layout_matches() {
    check::<GpuReservoir>();
}

#[test]
fn vpl_candidate_layout_matches() {
    check::<GpuVplCandidate>();
}

#[test]
fn vpl_params_layout_matches() {
    check::<GpuVplParams>();
}

#[test]
fn grid_params_layout_matches() {
    check::<GpuGridParams>();
}

#[test]
fn grid_entry_layout_matches() {
    check::<GpuGridEntry>();
}

#[test]
fn texture_layout_matches() {
    check::<GpuTexture>();
}

// ---- Passes -------------------------------------------------------------------------------------

/// One descriptor set's bindings as the SPIR-V declares them: binding -> (kind, or what the
/// variable is when no kind fits; name).
type ShaderBindings = BTreeMap<u32, (Result<BindingKind, String>, String)>;

/// Everything `desc` says that the SPIR-V `spirv` (its variant `variant`) contradicts, one message
/// per mismatch: set-1 bindings and set 0's against the scene's table (number, kind, name = the
/// block's first member or the variable's name), the push-constant block (member names, offsets, size) and the local size.
fn pass_mismatches(desc: &PassDesc, variant: &str, spirv: &[u8]) -> Vec<String> {
    let scene = if variant.starts_with("textured") { SCENE_BINDINGS_TEXTURED } else { SCENE_BINDINGS };
    pass_mismatches_against(desc, variant, spirv, scene)
}

/// [`pass_mismatches`] with set 0 compared against `scene`.
fn pass_mismatches_against(desc: &PassDesc, variant: &str, spirv: &[u8], scene: &[Binding]) -> Vec<String> {
    let at = format!("{} ({variant})", desc.name);
    let m = match Spirv::parse(spirv) {
        Ok(m) => m,
        Err(e) => return vec![format!("{at}: {e}")],
    };
    let mut out = Vec::new();

    // Sets 0 and 1: binding -> (kind, name) on both sides.
    let mut shader: [ShaderBindings; 2] = Default::default();
    let mut push = Vec::new();
    for (var, class, pointee) in m.variables() {
        if class == StorageClass::PushConstant {
            push.push(pointee);
            continue;
        }
        let set = match m.decorations.get(&(var, Decoration::DescriptorSet)) {
            Some(&set) if set <= 1 => set as usize,
            Some(set) => {
                out.push(format!("{at}: a variable in descriptor set {set} (only 0, the scene, and 1 exist)"));
                continue;
            }
            None => continue,
        };
        let Some(&binding) = m.decorations.get(&(var, Decoration::Binding)) else {
            out.push(format!("{at}: a set-{set} variable has no Binding"));
            continue;
        };
        let block_name = m.member_names.get(&(pointee, 0)).cloned();
        let accel = m.global(pointee).is_ok_and(|t| t.class.opcode == Op::TypeAccelerationStructureKHR);
        // A buffer image: sampled (Sampled = 1, `utextureBuffer`) is a uniform texel buffer,
        // storage (Sampled = 2, `uimageBuffer`) a storage texel buffer.
        let texel_buffer = |sampled: u32| {
            m.global(pointee).is_ok_and(|t| {
                t.class.opcode == Op::TypeImage
                    && matches!(t.operands.get(1), Some(Operand::Dim(Dim::DimBuffer)))
                    && t.operands.get(5).map(lit_u32) == Some(sampled)
            })
        };
        let entry = match class {
            StorageClass::StorageBuffer => (Ok(BindingKind::StorageBuffer), block_name),
            StorageClass::Uniform if m.decorations.contains_key(&(pointee, Decoration::BufferBlock)) => {
                (Ok(BindingKind::StorageBuffer), block_name)
            }
            StorageClass::Uniform => (Ok(BindingKind::UniformBuffer), block_name),
            StorageClass::UniformConstant if accel => (Ok(BindingKind::AccelerationStructure), m.names.get(&var).cloned()),
            StorageClass::UniformConstant if texel_buffer(1) => (Ok(BindingKind::UniformTexelBuffer), m.names.get(&var).cloned()),
            StorageClass::UniformConstant if texel_buffer(2) => (Ok(BindingKind::StorageTexelBuffer), m.names.get(&var).cloned()),
            other => (Err(format!("{other:?} variable")), m.names.get(&var).cloned()),
        };
        if shader[set].insert(binding, (entry.0, entry.1.unwrap_or_default())).is_some() {
            out.push(format!("{at}: the shader declares set {set} binding {binding} twice"));
        }
    }
    // Set 1 against the desc's table; set 0 against the scene's table of this variant (the
    // shaders declare it once, in shaders/common/scene.glsl).
    let [scene_shader, own_shader] = shader;
    binding_mismatches(&at, "", desc.bindings, &own_shader, &mut out);
    if !scene_shader.is_empty() {
        // The TLAS is declared by shaders/common/trace.glsl, which only the passes that trace
        // include (checked by `passes_that_trace_have_a_raygen_variant_and_no_other_traces`).
        let traces = scene_shader.values().any(|(kind, _)| *kind == Ok(BindingKind::AccelerationStructure));
        let scene: Vec<Binding> = scene.iter().copied().filter(|b| traces || b.kind != BindingKind::AccelerationStructure).collect();
        binding_mismatches(&at, "set 0 ", &scene, &scene_shader, &mut out);
    }
    // Push constants: top-level members and the block's size.
    match (push.as_slice(), desc.push.size) {
        ([], 0) => {}
        ([], _) => out.push(format!("{at}: the desc has {} bytes of push constants, the shader none", desc.push.size)),
        ([_, _, ..], _) => out.push(format!("{at}: the shader has more than one push-constant block")),
        ([block], size) => {
            let glsl: Vec<(String, u32, String)> =
                m.layout_of(*block).into_iter().zip(m.member_types(*block)).map(|((n, o), t)| (n, o, t)).collect();
            let rust: Vec<(String, u32, String)> = desc.push.fields.iter().map(|(n, o, t)| (n.to_string(), *o as u32, t.to_string())).collect();
            let show = |f: Option<&(String, u32, String)>| f.map_or("absent".to_string(), |(n, o, t)| format!("{t} '{n}' at {o}"));
            for i in 0..glsl.len().max(rust.len()) {
                let (g, r) = (glsl.get(i), rust.get(i));
                if g != r {
                    out.push(format!("{at}: push member {i} is {} in the shader, {} in Rust", show(g), show(r)));
                }
            }
            match m.size_of(*block) {
                Ok(bytes) if bytes as usize == size => {}
                Ok(bytes) => out.push(format!("{at}: the push-constant block is {bytes} bytes in the shader, {size} in Rust")),
                Err(e) => out.push(format!("{at}: push-constant block size: {e}")),
            }
        }
    }

    // A ray-generation variant: no workgroup (its launch covers the same invocations).
    let raygen = variant.ends_with("raygen");
    let model = if raygen { ExecutionModel::RayGenerationKHR } else { ExecutionModel::GLCompute };
    if m.execution_models != [model] {
        out.push(format!("{at}: the entry points are {:?}, expected [{model:?}]", m.execution_models));
    }
    // Its specialisation constants beyond the workgroup's: (constant_id, name) as the desc lists
    // them, in every variant.
    let mut declared: Vec<(u32, String)> = m
        .decorations
        .iter()
        .filter(|((_, d), &id)| *d == Decoration::SpecId && id >= 2)
        .map(|((target, _), &id)| (id, m.names.get(target).cloned().unwrap_or_default()))
        .collect();
    declared.sort();
    let listed: Vec<(u32, String)> = desc.constants.iter().map(|&(id, name)| (id, name.to_string())).collect();
    if declared != listed {
        out.push(format!("{at}: specialisation constants {declared:?} in the shader, {listed:?} in the desc"));
    }
    if raygen {
        return out;
    }
    // Workgroup size.
    match m.local_size {
        Some(size) if size == desc.local_size => {}
        Some(size) => out.push(format!("{at}: local size is {size:?} in the shader, {:?} in the desc", desc.local_size)),
        None => out.push(format!("{at}: the shader has no literal LocalSize")),
    }
    // A specialisable workgroup: spec constants 0 and 1 exactly where the desc says so.
    let spec_ids: Vec<u32> =
        m.decorations.iter().filter(|((_, d), _)| *d == Decoration::SpecId).map(|(_, &id)| id).collect();
    let specialisable = spec_ids.contains(&0) && spec_ids.contains(&1);
    if specialisable != desc.workgroup_spec {
        out.push(format!(
            "{at}: the desc says workgroup_spec = {}, the shader {} local_size_x_id = 0 / local_size_y_id = 1",
            desc.workgroup_spec,
            if specialisable { "has" } else { "lacks" }
        ));
    }
    out
}

/// Mismatches between a binding table and the shader's bindings of one set (`set`: "" for set 1,
/// the pass's own, "set 0 " for the scene's), added to `out`.
fn binding_mismatches(
    at: &str,
    set: &str,
    bindings: &[Binding],
    shader: &ShaderBindings,
    out: &mut Vec<String>,
) {
    let mut table: BTreeMap<u32, (BindingKind, &str)> = BTreeMap::new();
    for b in bindings {
        if table.insert(b.binding, (b.kind, b.name)).is_some() {
            out.push(format!("{at}: the table lists {set}binding {} twice", b.binding));
        }
    }
    for (binding, (kind, name)) in &table {
        match shader.get(binding) {
            None => out.push(format!("{at}: {set}binding {binding} ('{name}') is in the table but not in the shader")),
            Some((Err(what), _)) => out.push(format!("{at}: {set}binding {binding} is a {what} in the shader")),
            Some((Ok(k), n)) => {
                if k != kind {
                    out.push(format!("{at}: {set}binding {binding} ('{name}') is {kind:?} in the table, {k:?} in the shader"));
                }
                if n != name {
                    out.push(format!("{at}: {set}binding {binding} is '{name}' in the table, '{n}' in the shader"));
                }
            }
        }
    }
    for (binding, (_, name)) in shader {
        if !table.contains_key(binding) {
            out.push(format!("{at}: {set}binding {binding} ('{name}') is in the shader but not in the table"));
        }
    }

}

/// Every mismatch of `desc` over all its SPIR-V variants.
fn all_mismatches(desc: &PassDesc) -> Vec<String> {
    desc.spirv_variants().iter().flat_map(|(variant, spirv)| pass_mismatches(desc, variant, spirv)).collect()
}

#[test]
fn every_pass_desc_matches_its_spirv() {
    let mismatches: Vec<String> = passes::all_pass_descs().into_iter().flat_map(all_mismatches).collect();
    assert!(mismatches.is_empty(), "pass descs and SPIR-V differ:\n{}", mismatches.join("\n"));
}

/// Whether a module declares the ray-query / ray-tracing-pipeline capability.
fn capabilities(spirv: &[u8]) -> (bool, bool) {
    let m = Spirv::parse(spirv).expect("build.rs's SPIR-V parses");
    (m.capabilities.contains(&Capability::RayQueryKHR), m.capabilities.contains(&Capability::RayTracingKHR))
}

/// A pass that traces (its compute SPIR-V uses ray queries) has a ray-generation variant for every
/// compute variant, and that variant traces through the pipeline (no ray queries); a pass that does
/// not trace declares neither capability, so that a device with ray-tracing pipelines and no ray
/// queries (NVIDIA's H100) accepts every module it is given.
#[test]
fn passes_that_trace_have_a_raygen_variant_and_no_other_traces() {
    let mut problems = Vec::new();
    let mut tracing = 0;
    for d in passes::all_pass_descs() {
        let (query, pipeline) = capabilities(d.spirv);
        if pipeline {
            problems.push(format!("{}: the compute variant declares RayTracingKHR", d.name));
        }
        if query != d.raygen.is_some() {
            problems.push(format!("{}: ray queries {query}, raygen variant {}", d.name, d.raygen.is_some()));
        }
        if d.raygen.is_some() && d.textured.is_some() != d.textured_raygen.is_some() {
            problems.push(format!("{}: a textured variant without its raygen twin, or the reverse", d.name));
        }
        for (variant, spirv) in [("raygen", d.raygen), ("textured_raygen", d.textured_raygen)] {
            if let Some(spirv) = spirv {
                match capabilities(spirv) {
                    (false, true) => {}
                    other => problems.push(format!("{} ({variant}): (ray query, ray tracing) capabilities {other:?}", d.name)),
                }
            }
        }
        tracing += usize::from(query);
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    // The passes that trace: gbuffer, pathtrace, photon_emit, vpl_compensate, vpl_shade,
    // vpl_bruteforce and the five ReSTIR passes.
    assert_eq!(tracing, 11, "passes with ray queries");
}

/// `bench --rays`' kernel (shaders/bench/ray_rate.comp) is not a frame pass but has the same
/// interface checks.
#[test]
fn the_ray_rate_kernel_desc_matches_its_spirv() {
    let mismatches = all_mismatches(&restir_vpl::eval::rays::RAY_RATE_DESC);
    assert!(mismatches.is_empty(), "ray_rate's desc and SPIR-V differ:\n{}", mismatches.join("\n"));
}

/// Each `shaders/passes/<name>.comp` has exactly one desc named `<name>`, and vice versa.
#[test]
fn every_pass_shader_has_one_desc() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders/passes");
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .expect("shaders/passes is readable")
        .filter_map(|e| {
            let path = e.expect("directory entry").path();
            (path.extension()? == "comp").then(|| path.file_stem()?.to_str().map(str::to_string))?
        })
        .collect();
    files.sort();
    let mut descs: Vec<String> = passes::all_pass_descs().iter().map(|d| d.name.to_string()).collect();
    descs.sort();
    assert_eq!(files, descs, "shaders/passes/*.comp (left) vs passes::ALL_PASSES (right)");
}

/// Asserts that `drifted` is reported with a message containing `needle`.
fn assert_reported(drifted: &PassDesc, needle: &str) {
    let mismatches = all_mismatches(drifted);
    assert!(
        mismatches.iter().any(|m| m.contains(needle)),
        "expected a mismatch mentioning {needle:?}, got {mismatches:?}"
    );
}

#[test]
fn a_drifted_binding_table_is_detected() {
    // Binding number: tonemap's second buffer declared at 2 instead of 1 (missing on both sides).
    const MOVED: PassDesc = TonemapPass::DESC.with_bindings(&[storage(0, "means"), storage(2, "preview")]);
    let moved = MOVED;
    assert_reported(&moved, "binding 2 ('preview') is in the table but not in the shader");
    assert_reported(&moved, "binding 1 ('preview') is in the shader but not in the table");
    // Name.
    const RENAMED: PassDesc = TonemapPass::DESC.with_bindings(&[storage(0, "mean"), storage(1, "preview")]);
    let renamed = RENAMED;
    assert_reported(&renamed, "binding 0 is 'mean' in the table, 'means' in the shader");
    // Kind.
    const UNIFORM: PassDesc = TonemapPass::DESC.with_bindings(&[uniform(0, "means"), storage(1, "preview")]);
    let uniform = UNIFORM;
    assert_reported(&uniform, "is UniformBuffer in the table, StorageBuffer in the shader");
    // A storage buffer declared as a storage texel buffer (gbuffer writes through storage buffers).
    let mut chunks = GbufferPass::DESC.bindings.to_vec();
    chunks[3] = storage_texels(3, "surfaces_chunk3");
    let as_texels = PassDesc { bindings: chunks.leak(), ..GbufferPass::DESC };
    assert_reported(&as_texels, "binding 3 ('surfaces_chunk3') is StorageTexelBuffer in the table, StorageBuffer in the shader");
    // A texel view declared as a storage buffer (spatial reads its surfaces as texels).
    const AS_STORAGE: PassDesc = RestirSpatialPass::DESC.with_bindings(&[
        storage(0, "surfaces"), texels(1, "vpls"), texels(2, "src"), storage(3, "dst"), storage(4, "ray_count"),
    ]);
    let as_storage = AS_STORAGE;
    assert_reported(&as_storage, "binding 0 ('surfaces') is StorageBuffer in the table, UniformTexelBuffer in the shader");
    // A binding on one side only: the table lacks accumulate's last one.
    let short = PassDesc { bindings: &AccumulatePass::DESC.bindings[..5], ..AccumulatePass::DESC };
    assert_reported(&short, "binding 5 ('nonfinite_samples') is in the shader but not in the table");
    // Also checked in the textured variant.
    assert_reported(&as_texels, "gbuffer (textured): binding 3 ('surfaces_chunk3') is StorageTexelBuffer");
}

#[test]
fn a_drifted_scene_table_is_detected() {
    let spirv = GbufferPass::DESC.spirv_variants();
    let [(_, plain), (_, textured), ..] = spirv.as_slice() else { panic!("gbuffer has a default and a textured variant") };
    let at = |scene: &[Binding], spirv: &[u8]| pass_mismatches_against(&GbufferPass::DESC, "default", spirv, scene);
    // The textured variant's texture bindings against the plain table.
    assert!(at(SCENE_BINDINGS, textured).iter().any(|m| m.contains("set 0 binding 9 ('textures') is in the shader but not in the table")));
    assert!(at(SCENE_BINDINGS_TEXTURED, plain).iter().any(|m| m.contains("set 0 binding 10 ('texels') is in the table but not in the shader")));
    // A renamed and a retyped row.
    let mut rows = SCENE_BINDINGS.to_vec();
    rows[6] = texels(6, "light_list");
    rows[8] = storage(8, "frame");
    let found = at(&rows, plain);
    assert!(found.iter().any(|m| m.contains("set 0 binding 6 is 'light_list' in the table, 'lights' in the shader")), "{found:?}");
    assert!(found.iter().any(|m| m.contains("set 0 binding 8 ('frame') is StorageBuffer in the table, UniformBuffer in the shader")), "{found:?}");
    assert!(at(SCENE_BINDINGS, plain).is_empty());
}

#[test]
fn a_drifted_push_layout_is_detected() {
    let d = RestirSpatialPass::DESC;
    // Offset: `neighbours` follows the 32-byte VplParams.
    let fields: Vec<(&'static str, usize, &'static str)> =
        d.push.fields.iter().map(|&(n, o, t)| if n == "neighbours" { (n, o + 4, t) } else { (n, o, t) }).collect();
    let shifted = PassDesc { push: PushLayout { fields: fields.leak(), ..d.push }, ..d };
    assert_reported(&shifted, "push member 1 is uint 'neighbours' at 32 in the shader, uint 'neighbours' at 36 in Rust");
    // Name.
    let fields: Vec<(&'static str, usize, &'static str)> =
        d.push.fields.iter().map(|&(n, o, t)| if n == "radius" { ("radius_px", o, t) } else { (n, o, t) }).collect();
    let renamed = PassDesc { push: PushLayout { fields: fields.leak(), ..d.push }, ..d };
    assert_reported(&renamed, "push member 3 is float 'radius' at 40 in the shader, float 'radius_px' at 40 in Rust");
    // Type: a uint where the shader has a float, at the same offset (names and offsets alone
    // passed it).
    let fields: Vec<(&'static str, usize, &'static str)> =
        d.push.fields.iter().map(|&(n, o, t)| if n == "radius" { (n, o, "uint") } else { (n, o, t) }).collect();
    let retyped = PassDesc { push: PushLayout { fields: fields.leak(), ..d.push }, ..d };
    assert_reported(&retyped, "push member 3 is float 'radius' at 40 in the shader, uint 'radius' at 40 in Rust");
    // A nested struct by its name.
    assert!(d.push.fields[0].2 == "VplParams", "{:?}", d.push.fields[0]);
    // Size.
    let bigger = PassDesc { push: PushLayout { size: d.push.size + 4, ..d.push }, ..d };
    assert_reported(&bigger, &format!("is {} bytes in the shader, {} in Rust", d.push.size, d.push.size + 4));
    // Push constants on one side only.
    let none = PassDesc { push: PushLayout::NONE, ..VplShadePass::DESC };
    assert_reported(&none, "push member 0 is VplParams 'params' at 0 in the shader, absent in Rust");
    let phantom = PassDesc { push: VplShadePass::DESC.push, ..TonemapPass::DESC };
    assert_reported(&phantom, "push constants, the shader none");
}

#[test]
fn a_drifted_local_size_is_detected() {
    let wide = PassDesc { local_size: [16, 8, 1], ..GbufferPass::DESC };
    assert_reported(&wide, "local size is [8, 8, 1] in the shader, [16, 8, 1] in the desc");
    let flat = PassDesc { local_size: [8, 8, 1], ..AccumulatePass::DESC };
    assert_reported(&flat, "local size is [64, 1, 1] in the shader");
}

#[test]
fn a_raygen_variant_that_is_a_compute_shader_is_detected() {
    let wrong = PassDesc { raygen: Some(GbufferPass::DESC.spirv), ..GbufferPass::DESC };
    assert_reported(&wrong, "gbuffer (raygen): the entry points are [GLCompute], expected [RayGenerationKHR]");
}

#[test]
fn a_specialisation_constant_that_drifted_is_detected() {
    let fewer = PassDesc { constants: &[(2, "UNBIASED")], ..RestirSpatialPass::DESC };
    assert_reported(&fewer, "restir_spatial (default): specialisation constants [(2, \"UNBIASED\"), (3, \"VISIBLE_TARGETS\")] in the shader");
    assert_reported(&fewer, "restir_spatial (raygen): specialisation constants");
    let renamed = PassDesc { constants: &[(2, "UNBIASED"), (3, "VISIBLE")], ..RestirSpatialPass::DESC };
    assert_reported(&renamed, "in the desc");
    let stray = PassDesc { constants: &[(2, "UNBIASED")], ..RestirTemporalPass::DESC };
    assert_reported(&stray, "restir_temporal (default): specialisation constants [] in the shader");
}

#[test]
fn a_workgroup_spec_flag_that_drifted_is_detected() {
    let fixed = PassDesc { workgroup_spec: false, ..GbufferPass::DESC };
    assert_reported(&fixed, "the desc says workgroup_spec = false, the shader has local_size_x_id");
    let spec = PassDesc { workgroup_spec: true, ..RestirTemporalPass::DESC };
    assert_reported(&spec, "the desc says workgroup_spec = true, the shader lacks local_size_x_id");
}

// ---- Constants ----------------------------------------------------------------------------------

/// Every disagreement between the `const uint NAME = Vu;` declarations of `header` and the Rust
/// constants `rust`: a value that differs, a constant on one side only, a `const` line that does
/// not parse.
fn constant_mismatches(header: &str, rust: &[(&str, u32)]) -> Vec<String> {
    let mut out = Vec::new();
    let mut glsl: BTreeMap<String, u32> = BTreeMap::new();
    for (i, line) in header.lines().enumerate() {
        let code = line.split("//").next().unwrap_or_default().trim();
        if !code.starts_with("const ") {
            continue;
        }
        let parsed = code
            .strip_prefix("const uint ")
            .and_then(|rest| rest.strip_suffix(';'))
            .and_then(|decl| decl.split_once('='))
            .and_then(|(name, value)| Some((name.trim(), parse_uint(value.trim())?)));
        match parsed {
            Some((name, value)) => {
                if glsl.insert(name.to_string(), value).is_some() {
                    out.push(format!("{name} is declared twice in GLSL"));
                }
            }
            None => out.push(format!("line {}: not `const uint NAME = <u32>u;`: {code}", i + 1)),
        }
    }
    let mut seen = BTreeMap::new();
    for &(name, value) in rust {
        if seen.insert(name, value).is_some() {
            out.push(format!("{name} is listed twice in Rust"));
        }
        match glsl.get(name) {
            None => out.push(format!("{name} = {value} has no GLSL twin")),
            Some(&v) if v != value => out.push(format!("{name} is {v} in GLSL, {value} in Rust")),
            Some(_) => {}
        }
    }
    for (name, value) in &glsl {
        if !seen.contains_key(name.as_str()) {
            out.push(format!("{name} = {value} (GLSL) has no Rust twin"));
        }
    }
    out
}

/// A GLSL `uint` literal: `12u` or `0xFFu`.
fn parse_uint(literal: &str) -> Option<u32> {
    let digits = literal.strip_suffix(['u', 'U'])?;
    match digits.strip_prefix("0x").or_else(|| digits.strip_prefix("0X")) {
        Some(hex) => u32::from_str_radix(hex, 16).ok(),
        None => digits.parse().ok(),
    }
}

fn types_glsl() -> String {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders/common/types.glsl");
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn glsl_constants_match_rust() {
    let mismatches = constant_mismatches(&types_glsl(), &passes::glsl_constants());
    assert!(mismatches.is_empty(), "shaders/common/types.glsl and Rust differ:\n{}", mismatches.join("\n"));
}

#[test]
fn a_drifted_constant_is_detected() {
    let header = types_glsl();
    let rust = passes::glsl_constants();
    let changed = header.replace("const uint VPL_FLAG_UNBIASED = 2u;", "const uint VPL_FLAG_UNBIASED = 8u;");
    assert_ne!(changed, header, "the header declares VPL_FLAG_UNBIASED = 2u");
    assert_eq!(constant_mismatches(&changed, &rust), vec!["VPL_FLAG_UNBIASED is 8 in GLSL, 2 in Rust".to_string()]);
    // A ray-counter slot.
    let changed = header.replace("const uint RAYS_SHADE = 4u;", "const uint RAYS_SHADE = 0x5u;");
    assert_eq!(constant_mismatches(&changed, &rust), vec!["RAYS_SHADE is 5 in GLSL, 4 in Rust".to_string()]);
    // One side only.
    let extra = format!("{header}\nconst uint SHADE_VIEW_EXTRA = 9u;\n");
    assert_eq!(constant_mismatches(&extra, &rust), vec!["SHADE_VIEW_EXTRA = 9 (GLSL) has no Rust twin".to_string()]);
    let missing = header.replace("const uint FRAME_AA = 1u;", "");
    assert_eq!(constant_mismatches(&missing, &rust), vec!["FRAME_AA = 1 has no GLSL twin".to_string()]);
    // A declaration the check cannot read is an error, not skipped.
    let float = format!("{header}\nconst float PI = 3.14159;\n");
    assert!(constant_mismatches(&float, &rust).iter().any(|m| m.contains("const float PI")));
}

/// Devices are refused (with the reason in their report) unless a shader stage may see as many
/// storage buffers as the hungriest pass declares with a textured scene's set 0; the constant the
/// device check uses must be that count.
#[test]
fn the_device_check_asks_for_the_storage_buffers_a_pass_uses() {
    assert_eq!(passes::storage_buffers_per_stage(), restir_vpl::vk::context::REQUIRED_STORAGE_BUFFERS_PER_STAGE);
}

/// Set-1 bindings of `spirv` that some function reads or writes (an instruction in a function body
/// names the binding's variable), as opposed to bindings only declared; and the names of the
/// functions the module holds (glslang names them `name(signature`).
fn used_set1_bindings_and_functions(spirv: &[u8]) -> (Vec<u32>, Vec<String>) {
    let module = rspirv::dr::load_bytes(spirv).expect("build.rs's SPIR-V parses");
    let decoration = |target: u32, which: Decoration| {
        module.annotations.iter().find_map(|i| match i.operands.as_slice() {
            [Operand::IdRef(t), Operand::Decoration(d), value] if *t == target && *d == which => Some(lit_u32(value)),
            _ => None,
        })
    };
    let body = || module.functions.iter().flat_map(|f| f.blocks.iter().flat_map(|b| b.instructions.iter()));
    let mut used: Vec<u32> = module
        .types_global_values
        .iter()
        .filter(|i| i.class.opcode == Op::Variable)
        .filter_map(|i| i.result_id)
        .filter(|&id| decoration(id, Decoration::DescriptorSet) == Some(1))
        .filter(|&id| body().any(|inst| inst.operands.iter().any(|o| matches!(o, Operand::IdRef(r) if *r == id))))
        .filter_map(|id| decoration(id, Decoration::Binding))
        .collect();
    used.sort_unstable();
    let function_ids: Vec<u32> = module.functions.iter().filter_map(|f| f.def.as_ref().and_then(|d| d.result_id)).collect();
    let functions = module
        .debug_names
        .iter()
        .filter_map(|i| match i.operands.as_slice() {
            [Operand::IdRef(id), Operand::LiteralString(name)] if function_ids.contains(id) => Some(name.clone()),
            _ => None,
        })
        .collect();
    (used, functions)
}

/// The ReGIR grid lives in the passes' `grid` variants only: the default variants of
/// `restir_initial` and `restir_initial_temporal` hold none of the grid's functions and never touch
/// its cells, so a pass without a grid runs none of the grid's code (on lavapipe that code, left
/// to the driver to skip, cost 50 % of `restir_initial` with the grid off); the grid variants hold
/// them all and stamp the cells.
#[test]
fn only_the_grid_variants_hold_the_grid_code() {
    const GRID_FUNCTIONS: [&str; 4] = ["regir_cell(", "regir_cell_target(", "grid_entry_ucw_texels(", "grid_entry_candidate_texels("];
    for d in [&passes::RestirInitialPass::DESC, &passes::RestirInitialTemporalPass::DESC] {
        let cells = d.bindings.iter().find(|b| b.name == "grid_cells").expect("a grid_cells binding").binding;
        for (variant, spirv) in d.spirv_variants() {
            let (used, functions) = used_set1_bindings_and_functions(spirv);
            let held: Vec<&str> = GRID_FUNCTIONS.iter().copied().filter(|f| functions.iter().any(|n| n.starts_with(f))).collect();
            if variant.starts_with("grid") {
                assert_eq!(held, GRID_FUNCTIONS, "{} ({variant}) holds the grid's functions", d.name);
                assert!(used.contains(&cells), "{} ({variant}) stamps the grid's cells: {used:?}", d.name);
            } else {
                assert!(held.is_empty(), "{} ({variant}) holds grid functions {held:?}", d.name);
                assert!(!used.contains(&cells), "{} ({variant}) touches grid_cells: {used:?}", d.name);
                // The check sees functions and uses at all.
                assert!(functions.iter().any(|n| n.starts_with("initial_reservoir(")), "{} ({variant}): {functions:?}", d.name);
                assert!(used.len() >= 4, "{} ({variant}): used set-1 bindings {used:?}", d.name);
            }
        }
    }
}

/// triangle_normal's cross product is `precise` (shaders/lib/sampling.glsl) in every module that
/// holds the function: its 6 multiplications and 3 subtractions carry NoContraction, so no
/// driver contracts them into FMAs, whose rounding residue where the exact component is 0 (a
/// triangle with an edge along an axis) flipped onb()'s frame with the scene's scale on an H100. Guards against
/// the `cross()` builtin (one extended instruction: no decoration reaches inside it) coming back.
#[test]
fn triangle_normal_forbids_contraction_everywhere() {
    let mut checked = 0;
    let mut problems = Vec::new();
    for d in passes::all_pass_descs() {
        for (variant, spirv) in d.spirv_variants() {
            let module = rspirv::dr::load_bytes(spirv).expect("build.rs's SPIR-V parses");
            let id = module.debug_names.iter().find_map(|i| match i.operands.as_slice() {
                [Operand::IdRef(id), Operand::LiteralString(name)] if name.starts_with("triangle_normal(") => Some(*id),
                _ => None,
            });
            let Some(function) = id.and_then(|id| module.functions.iter().find(|f| f.def.as_ref().and_then(|d| d.result_id) == Some(id))) else {
                continue;
            };
            let precise: Vec<u32> = module
                .annotations
                .iter()
                .filter_map(|i| match i.operands.as_slice() {
                    [Operand::IdRef(t), Operand::Decoration(Decoration::NoContraction)] => Some(*t),
                    _ => None,
                })
                .collect();
            let count = |op: Op| {
                function
                    .blocks
                    .iter()
                    .flat_map(|b| b.instructions.iter())
                    .filter(|i| i.class.opcode == op && i.result_id.is_some_and(|r| precise.contains(&r)))
                    .count()
            };
            let (mul, sub) = (count(Op::FMul), count(Op::FSub));
            if mul < 6 || sub < 3 {
                problems.push(format!("{} ({variant}): {mul} multiplications and {sub} subtractions with NoContraction", d.name));
            }
            checked += 1;
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    // photon_emit, pathtrace, gbuffer and every pass that shades a hit hold it.
    assert!(checked >= 4, "only {checked} modules hold triangle_normal");
}
