//! VPL point clouds as binary little-endian PLY: x y z nx ny nz (float), flux_r flux_g flux_b
//! (float), kind (uchar), red green blue (uchar: blue for direct, red for indirect). MeshLab and
//! Blender open it as is.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::Path;

use anyhow::{bail, Context as _, Result};

use crate::gpu_types::{GpuVpl, VPL_INDIRECT};

const PROPERTIES: [(&str, &str); 13] = [
    ("float", "x"),
    ("float", "y"),
    ("float", "z"),
    ("float", "nx"),
    ("float", "ny"),
    ("float", "nz"),
    ("float", "flux_r"),
    ("float", "flux_g"),
    ("float", "flux_b"),
    ("uchar", "kind"),
    ("uchar", "red"),
    ("uchar", "green"),
    ("uchar", "blue"),
];

/// Writes the VPLs to `path` (replacing it whole: a failed write leaves the earlier file), their
/// positions moved by `origin` (the scene's [`crate::scene::Scene::origin`]: into the file's
/// coordinates). Errors name the file; the caller names the flag (`--dump-vpls`, or
/// `--dump-passes`' `passes/vpls.ply`).
pub fn write_vpls(path: &Path, vpls: &[GpuVpl], origin: glam::Vec3) -> Result<()> {
    // As --out: a missing directory is created.
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create the directory {}", path.display(), dir.display()))?;
    }
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment restir-vpl virtual point lights: flux in W; kind 0 direct area, 1 direct point, 2 indirect\nelement vertex {}\n",
        vpls.len()
    );
    for (ty, name) in PROPERTIES {
        header += &format!("property {ty} {name}\n");
    }
    header += "end_header\n";
    crate::output::write_replacing(path, |partial| {
        // (write_replacing names the file in its errors: "writing PATH: ...".)
        let mut w = std::io::BufWriter::new(std::fs::File::create(partial)?);
        w.write_all(header.as_bytes())?;
        for v in vpls {
            let position = (glam::Vec3::from(v.position).as_dvec3() + origin.as_dvec3()).as_vec3().to_array();
            for f in position.iter().chain(&v.normal).chain(&v.flux) {
                w.write_all(&f.to_le_bytes())?;
            }
            let colour: [u8; 3] = if v.kind == VPL_INDIRECT { [230, 40, 30] } else { [30, 80, 240] };
            w.write_all(&[v.kind as u8])?;
            w.write_all(&colour)?;
        }
        w.flush()?;
        Ok(())
    })
}

/// Reads a PLY written by [`write_vpls`] back (used by tests; checks the header strictly).
pub fn read_vpls(path: &Path) -> Result<Vec<GpuVpl>> {
    let file = std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
    let mut r = BufReader::new(file);
    let mut line = String::new();
    let mut count = None;
    let mut props = Vec::new();
    loop {
        line.clear();
        if r.read_line(&mut line)? == 0 {
            bail!("{}: no end_header", path.display());
        }
        let l = line.trim_end();
        if l == "end_header" {
            break;
        }
        let parts: Vec<&str> = l.split_whitespace().collect();
        match parts.as_slice() {
            ["element", "vertex", n] => count = Some(n.parse::<usize>()?),
            ["property", ty, name] => props.push((ty.to_string(), name.to_string())),
            ["format", f, _] if *f != "binary_little_endian" => bail!("{}: format {f} not supported", path.display()),
            _ => {}
        }
    }
    let expected: Vec<(String, String)> = PROPERTIES.iter().map(|(t, n)| (t.to_string(), n.to_string())).collect();
    if props != expected {
        bail!("{}: unexpected vertex properties {props:?}", path.display());
    }
    let n = count.with_context(|| format!("{}: no vertex element", path.display()))?;
    let mut out = Vec::with_capacity(n);
    let mut rec = [0u8; 40];
    for _ in 0..n {
        r.read_exact(&mut rec)?;
        let f = |i: usize| f32::from_le_bytes(rec[i * 4..i * 4 + 4].try_into().expect("4 bytes"));
        out.push(GpuVpl {
            position: [f(0), f(1), f(2)],
            kind: rec[36] as u32,
            normal: [f(3), f(4), f(5)],
            path: 0,
            flux: [f(6), f(7), f(8)],
            yuksel_r2: 0.0,
        });
    }
    Ok(out)
}
