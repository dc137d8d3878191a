//! Rust and GLSL agree on every GPU struct: member names, byte offsets and sizes.
//!
//! `shaders/tests/layout.comp` declares one buffer per struct of `shaders/common/types.glsl`; glslang
//! assigns std430 (and, for `Frame`, std140) offsets. We read them back from the SPIR-V
//! (OpMemberName + OpMemberDecorate Offset, OpDecorate ArrayStride of the runtime arrays) and compare
//! them with `GpuStruct::FIELDS` (generated from the Rust fields by `offset_of!`).

use std::collections::HashMap;

use rspirv::dr::{Instruction, Operand};
use rspirv::spirv::{Decoration, Op};

use restir_vpl::gpu_types::*;

struct Reflection {
    names: HashMap<u32, String>,
    member_names: HashMap<(u32, u32), String>,
    offsets: HashMap<(u32, u32), u32>,
    array_strides: HashMap<u32, u32>,
    runtime_array_elem: HashMap<u32, u32>,
    struct_members: HashMap<u32, usize>,
    uniform_block_members: Vec<(u32, u32)>,
}

fn lit_u32(op: &Operand) -> u32 {
    match op {
        Operand::LiteralBit32(v) => *v,
        Operand::IdRef(v) => *v,
        other => panic!("unexpected operand {other:?}"),
    }
}

fn reflect() -> Reflection {
    let module = rspirv::dr::load_bytes(restir_vpl::shaders::TESTS_LAYOUT).expect("layout.comp SPIR-V parses");
    let mut r = Reflection {
        names: HashMap::new(),
        member_names: HashMap::new(),
        offsets: HashMap::new(),
        array_strides: HashMap::new(),
        runtime_array_elem: HashMap::new(),
        struct_members: HashMap::new(),
        uniform_block_members: Vec::new(),
    };
    for inst in module.debug_names.iter() {
        match inst.class.opcode {
            Op::Name => {
                if let Operand::LiteralString(s) = &inst.operands[1] {
                    r.names.insert(lit_u32(&inst.operands[0]), s.clone());
                }
            }
            Op::MemberName => {
                if let Operand::LiteralString(s) = &inst.operands[2] {
                    r.member_names.insert((lit_u32(&inst.operands[0]), lit_u32(&inst.operands[1])), s.clone());
                }
            }
            _ => {}
        }
    }
    for inst in module.annotations.iter() {
        decode_annotation(inst, &mut r);
    }
    for inst in module.types_global_values.iter() {
        match inst.class.opcode {
            Op::TypeRuntimeArray => {
                r.runtime_array_elem.insert(inst.result_id.expect("type id"), lit_u32(&inst.operands[0]));
            }
            Op::TypeStruct => {
                let id = inst.result_id.expect("type id");
                r.struct_members.insert(id, inst.operands.len());
                if r.names.get(&id).is_some_and(|n| n == "B7") {
                    r.uniform_block_members.push((id, lit_u32(&inst.operands[0])));
                }
            }
            _ => {}
        }
    }
    r
}

fn decode_annotation(inst: &Instruction, r: &mut Reflection) {
    match inst.class.opcode {
        Op::MemberDecorate => {
            if inst.operands[2] == Operand::Decoration(Decoration::Offset) {
                let key = (lit_u32(&inst.operands[0]), lit_u32(&inst.operands[1]));
                r.offsets.insert(key, lit_u32(&inst.operands[3]));
            }
        }
        Op::Decorate => {
            if inst.operands[1] == Operand::Decoration(Decoration::ArrayStride) {
                r.array_strides.insert(lit_u32(&inst.operands[0]), lit_u32(&inst.operands[2]));
            }
        }
        _ => {}
    }
}

/// (member names, offsets) of a struct type id.
fn layout_of(r: &Reflection, id: u32) -> Vec<(String, u32)> {
    (0..r.struct_members[&id] as u32)
        .map(|m| {
            let name = r.member_names.get(&(id, m)).cloned().unwrap_or_else(|| format!("#{m}"));
            let off = *r.offsets.get(&(id, m)).unwrap_or_else(|| panic!("member {name} has no Offset"));
            (name, off)
        })
        .collect()
}

/// The std430 struct named `glsl` used as the element of a runtime array: (layout, array stride).
fn std430_struct(r: &Reflection, glsl: &str) -> (Vec<(String, u32)>, u32) {
    let (arr, elem) = r
        .runtime_array_elem
        .iter()
        .find(|(_, e)| r.names.get(e).is_some_and(|n| n == glsl))
        .unwrap_or_else(|| panic!("layout.comp has no runtime array of {glsl}"));
    (layout_of(r, *elem), r.array_strides[arr])
}

fn check<T: GpuStruct>() {
    let r = reflect();
    let (glsl, stride) = std430_struct(&r, T::GLSL_NAME);
    let rust: Vec<(String, u32)> = T::FIELDS.iter().map(|(n, o)| (n.to_string(), *o as u32)).collect();
    assert_eq!(glsl, rust, "{}: GLSL (left) and Rust (right) members/offsets differ", T::GLSL_NAME);
    assert_eq!(stride as usize, std::mem::size_of::<T>(), "{}: std430 array stride vs Rust size", T::GLSL_NAME);
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
    let r = reflect();
    let (_, frame_std140) = r.uniform_block_members.first().copied().expect("uniform block B7 found");
    let glsl = layout_of(&r, frame_std140);
    let rust: Vec<(String, u32)> = GpuFrame::FIELDS.iter().map(|(n, o)| (n.to_string(), *o as u32)).collect();
    assert_eq!(glsl, rust, "Frame under std140 differs from the Rust layout");
}

/// The check itself can fail: a deliberately different field list is rejected.
#[test]
fn a_drifted_layout_is_detected() {
    let r = reflect();
    let (glsl, _) = std430_struct(&r, "Light");
    let mut drifted: Vec<(String, u32)> = GpuLight::FIELDS.iter().map(|(n, o)| (n.to_string(), *o as u32)).collect();
    drifted.swap(0, 1);
    assert_ne!(glsl, drifted);
}

#[test]
fn reservoir_layout_matches() {
    check::<GpuReservoir>();
}

#[test]
fn vpl_params_layout_matches() {
    check::<GpuVplParams>();
}

#[test]
fn texture_layout_matches() {
    check::<GpuTexture>();
}
