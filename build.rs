//! Compiles every shader under `shaders/` (compute `.comp`, and the ray-tracing pipeline's closest-hit
//! `.rchit` and miss `.rmiss`) to SPIR-V 1.5 (Vulkan 1.2 target) with glslang and generates
//! `$OUT_DIR/shaders.rs`, which embeds each module with `include_bytes!`.
//!
//! - `#include "x.glsl"` resolves relative to the including file, then relative to `shaders/`.
//! - Every file read (sources and includes) gets a `cargo:rerun-if-changed`.
//! - A compile error prints glslang's whole log and fails the build.
//! - Shader variants are listed in `VARIANTS`: (source, variant name, defines).
//! - The passes that trace rays are also compiled as ray-generation shaders (`RAYGEN`: variant
//!   `raygen`, and `textured_raygen` where a textured variant exists), with `RT_PIPELINE` defined:
//!   shaders/common/trace.glsl then traces through a ray-tracing pipeline, for devices without ray
//!   queries.

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glslang::include::{IncludeHandler, IncludeResult, IncludeType};
use glslang::{
    Compiler, CompilerOptions, Program, ShaderInput, ShaderSource, ShaderStage, SourceLanguage, SpirvVersion,
    Target, VulkanVersion,
};

/// Extra compilations of one source with preprocessor defines: (source relative to `shaders/`,
/// variant suffix, defines). The default variant (no defines) of every `.comp` is always built.
/// The `textured` variants read base-colour textures (set 0 bindings 9 and 10); a scene without
/// textures (or `--textures off`) uses the default variants, which contain no texture code. The
/// `grid` variants take candidates from the ReGIR grid (`--grid-candidates`); without a grid the
/// default variants hold none of its code, which lavapipe would otherwise run in every candidate
/// loop (+50 % in `restir_initial` at 256², measured).
const VARIANTS: &[(&str, &str, &[(&str, &str)])] = &[
    ("passes/gbuffer.comp", "textured", &[("SCENE_TEXTURES", "1")]),
    ("passes/pathtrace.comp", "textured", &[("SCENE_TEXTURES", "1")]),
    ("passes/photon_emit.comp", "textured", &[("SCENE_TEXTURES", "1")]),
    ("passes/vpl_compensate.comp", "textured", &[("SCENE_TEXTURES", "1")]),
    ("passes/restir_initial.comp", "grid", &[("REGIR_GRID", "1")]),
    ("passes/restir_initial_temporal.comp", "grid", &[("REGIR_GRID", "1")]),
];

/// The passes that trace rays (they include shaders/common/trace.glsl), compiled a second time as
/// ray-generation shaders for the ray-tracing-pipeline implementation (`src/vk/pipeline.rs`).
const RAYGEN: &[&str] = &[
    "passes/gbuffer.comp",
    "passes/pathtrace.comp",
    "passes/photon_emit.comp",
    "passes/vpl_compensate.comp",
    "passes/vpl_shade.comp",
    "passes/vpl_bruteforce.comp",
    "passes/restir_initial.comp",
    "passes/restir_initial_temporal.comp",
    "passes/restir_temporal.comp",
    "passes/restir_spatial.comp",
    "passes/restir_spatial_shade.comp",
    "bench/ray_rate.comp",
];

/// One compilation: a source, its variant name ("" for the default), defines and stage.
struct Job {
    path: PathBuf,
    variant: String,
    defines: Vec<(&'static str, &'static str)>,
    stage: ShaderStage,
}

/// The stage a source compiles to, from its extension.
fn stage_of(path: &Path) -> Option<ShaderStage> {
    match path.extension()?.to_str()? {
        "comp" => Some(ShaderStage::Compute),
        "rchit" => Some(ShaderStage::ClosestHit),
        "rmiss" => Some(ShaderStage::Miss),
        _ => None,
    }
}

struct Includer {
    root: PathBuf,
    /// Directory of the file being compiled (glslang names the top-level includer "").
    main_dir: PathBuf,
    seen: BTreeSet<PathBuf>,
}

impl IncludeHandler for Includer {
    fn include(&mut self, _ty: IncludeType, header: &str, includer: &str, _depth: usize) -> Option<IncludeResult> {
        let includer_dir = match Path::new(includer).parent() {
            Some(dir) if !includer.is_empty() => dir.to_path_buf(),
            _ => self.main_dir.clone(),
        };
        let candidates = [includer_dir.join(header), self.root.join(header)];
        for c in candidates {
            if let Ok(mut data) = std::fs::read_to_string(&c) {
                let c = c.canonicalize().unwrap_or(c);
                self.seen.insert(c.clone());
                // The crate passes the text on as a C string and panics on a NUL byte: the
                // compiler reports this instead, with the file.
                if let Some(at) = data.find('\0') {
                    data = format!("#error a NUL byte at byte {at} (a shader is text)\n");
                }
                return Some(IncludeResult { name: c.to_string_lossy().into_owned(), data });
            }
        }
        None
    }
}

fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("cannot read shader directory {}: {e}", dir.display()))
        .filter_map(Result::ok)
        .map(|e| e.path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            collect(&p, out);
        } else if stage_of(&p).is_some() {
            out.push(p);
        }
    }
}

fn const_name(rel: &Path, variant: &str) -> String {
    let stem = rel.with_extension("");
    let mut s: String = stem
        .to_string_lossy()
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_uppercase() } else { '_' })
        .collect();
    if !variant.is_empty() {
        s.push('_');
        s.push_str(&variant.to_ascii_uppercase());
    }
    s
}

fn compile(
    compiler: &Compiler,
    root: &Path,
    path: &Path,
    defines: &[(&str, &str)],
    stage: ShaderStage,
    includes: &mut BTreeSet<PathBuf>,
) -> Result<Vec<u32>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    // The crate's conversion panics on a NUL byte (a C string); said here, naming the file.
    if let Some(at) = text.find('\0') {
        return Err(format!("{}: a NUL byte at byte {at} (a shader is text)", path.display()));
    }
    let source = ShaderSource::from(text);
    let options = CompilerOptions {
        source_language: SourceLanguage::GLSL,
        target: Target::Vulkan { version: VulkanVersion::Vulkan1_2, spirv_version: SpirvVersion::SPIRV1_5 },
        version_profile: None,
        messages: glslang::ShaderMessage::DEFAULT | glslang::ShaderMessage::DEBUG_INFO,
    };
    let defs: Vec<(&str, Option<&str>)> = defines.iter().map(|(k, v)| (*k, Some(*v))).collect();
    let main_dir = path.parent().map(Path::to_path_buf).unwrap_or_else(|| root.to_path_buf());
    let mut includer = Includer { root: root.to_path_buf(), main_dir, seen: BTreeSet::new() };
    let result = (|| {
        let input = ShaderInput::new(&source, stage, &options, Some(&defs[..]), Some(&mut includer))
            .map_err(|e| format!("{e}"))?;
        let shader = glslang::Shader::new(compiler, input).parse().map_err(|e| full_log(&e))?;
        let mut program = Program::new(compiler);
        program.add_shader(&shader);
        program.compile(stage).map_err(|e| full_log(&e))
    })();
    includes.extend(includer.seen);
    result.map_err(|log| format!("{}\n{log}", path.display()))
}

fn full_log(e: &glslang::error::GlslangError) -> String {
    use glslang::error::GlslangError as E;
    match e {
        E::PreprocessError(l) | E::ParseError(l) | E::MapIoError(l) | E::LinkError(l) => {
            let stage = match e {
                E::PreprocessError(_) => "preprocess",
                E::ParseError(_) => "parse",
                E::MapIoError(_) => "map io",
                _ => "link",
            };
            let mut s = format!("{stage} error:\n{}", l.log.trim_end());
            if !l.debug_log.trim().is_empty() {
                s.push_str(&format!("\n--- glslang debug log ---\n{}", l.debug_log.trim_end()));
            }
            s
        }
        other => format!("{other}"),
    }
}

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let root = manifest.join("shaders");
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed={}", root.display());

    let mut sources = Vec::new();
    collect(&root, &mut sources);
    let compiler = Compiler::acquire().expect("glslang compiler can be acquired once per process");

    let mut jobs: Vec<Job> = sources
        .iter()
        .map(|p| Job { path: p.clone(), variant: String::new(), defines: Vec::new(), stage: stage_of(p).expect("collect keeps known stages") })
        .collect();
    for (src, variant, defines) in VARIANTS {
        jobs.push(Job { path: root.join(src), variant: (*variant).to_string(), defines: defines.to_vec(), stage: ShaderStage::Compute });
    }
    for src in RAYGEN {
        let rt = ("RT_PIPELINE", "1");
        jobs.push(Job { path: root.join(src), variant: "raygen".to_string(), defines: vec![rt], stage: ShaderStage::RayGeneration });
        for (_, variant, defines) in VARIANTS.iter().filter(|v| v.0 == *src) {
            let defines = defines.iter().copied().chain([rt]).collect();
            jobs.push(Job { path: root.join(src), variant: format!("{variant}_raygen"), defines, stage: ShaderStage::RayGeneration });
        }
    }

    let mut generated = String::from("// @generated by build.rs: SPIR-V of every shader under shaders/.\n");
    let mut includes = BTreeSet::new();
    let mut errors = Vec::new();
    let mut spirv_hash: u64 = 0xcbf2_9ce4_8422_2325;
    for Job { path, variant, defines, stage } in &jobs {
        println!("cargo:rerun-if-changed={}", path.display());
        let rel = path.strip_prefix(&root).expect("shader sources are under shaders/");
        match compile(compiler, &root, path, defines, *stage, &mut includes) {
            Ok(words) => {
                let name = const_name(rel, variant);
                let file = out_dir.join(format!("{}.spv", name.to_ascii_lowercase()));
                let bytes = bytemuck_words(&words);
                spirv_hash = fnv1a(spirv_hash, &bytes);
                std::fs::write(&file, bytes).expect("write SPIR-V to OUT_DIR");
                let _ = writeln!(
                    generated,
                    "/// `shaders/{}`{}\npub const {name}: &[u8] = include_bytes!({:?});",
                    rel.display(),
                    if variant.is_empty() { String::new() } else { format!(" (variant `{variant}`: {defines:?})") },
                    file.display().to_string()
                );
            }
            Err(log) => errors.push(log),
        }
    }
    for inc in &includes {
        println!("cargo:rerun-if-changed={}", inc.display());
    }
    if !errors.is_empty() {
        for e in &errors {
            eprintln!("\n==== shader compile error ====\n{e}");
        }
        panic!("{} shader(s) failed to compile; glslang's full logs are printed above", errors.len());
    }
    let _ = writeln!(
        generated,
        "/// FNV-1a hash of every SPIR-V module above (names the persistent pipeline cache).\npub const SPIRV_HASH: u64 = {spirv_hash:#x};"
    );
    std::fs::write(out_dir.join("shaders.rs"), generated).expect("write shaders.rs");
}

fn fnv1a(mut h: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x100_0000_01b3);
    }
    h
}

fn bytemuck_words(words: &[u32]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}
