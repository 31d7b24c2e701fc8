//! The DEM ABI end to end with no external engine:
//! - the header `bindings/include/plugflow_dem.h` and the Rust declarations agree (every
//!   prototype, every status code, the version, the struct layouts as a C compiler sees them);
//! - a C program written against the header alone drives the library and gets bit for bit
//!   what the engine gives when called directly;
//! - the Rust loader (`AbiBackend`) running the coupled vertical case gives bit for bit what
//!   the built-in engine gives directly;
//! - the loader refuses a library of another major version, or one missing a required call.

use std::path::{Path, PathBuf};
use std::process::Command;

use plugflow::dem::NativeDem;
use plugflow::scene::Scene;
use plugflow::setup::coupling_from_scene;
use plugflow_coupling::abi::{self, AbiBackend, LoadError, PfDemFlow, PfDemInfo};
use plugflow_coupling::DemBackend;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// target/<profile>/, where cargo puts the cdylib next to the test's deps/ folder.
fn target_dir() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    exe.parent().unwrap().parent().unwrap().to_path_buf()
}

fn library() -> PathBuf {
    let lib = target_dir().join("libplugflow_dem_native.so");
    assert!(lib.exists(), "{} not built", lib.display());
    lib
}

/// A test's scratch directory: removed when the test passes, kept to look at when it fails.
struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

fn scratch(tag: &str) -> Scratch {
    let d = std::env::temp_dir().join(format!("plugflow-abi-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    Scratch(d)
}

fn header() -> String {
    std::fs::read_to_string(root().join("bindings/include/plugflow_dem.h")).unwrap()
}

/// C type (as written in a prototype, name removed) → the Rust type name of the loader.
fn rust_type(c: &str) -> String {
    let c = c.split_whitespace().collect::<Vec<_>>().join(" ");
    let c = c.replace(" *", "*");
    let (base, stars) = (c.trim_end_matches('*'), c.matches('*').count());
    let (is_const, base) = match base.strip_prefix("const ") {
        Some(b) => (true, b),
        None => (false, base),
    };
    let scalar = match base {
        "char" => "i8",
        "double" => "f64",
        "uint64_t" => "u64",
        "uint8_t" => "u8",
        "uint32_t" => "u32",
        "int32_t" | "pf_status" => "i32",
        "size_t" => "usize",
        "pf_dem" => "PfDem",
        "pf_dem_info" => "PfDemInfo",
        "pf_dem_flow" => "PfDemFlow",
        "void" => "()",
        other => panic!("unexpected C type `{other}`"),
    };
    let mut t = scalar.to_string();
    for k in 0..stars {
        // The innermost pointer carries the const.
        let q = if k == 0 && is_const {
            "*const "
        } else {
            "*mut "
        };
        t = format!("{q}{t}");
    }
    t
}

/// Prototypes of the header: name → `unsafe extern "C" fn(..) -> ..` as Rust prints it.
fn header_prototypes(text: &str) -> Vec<(String, String)> {
    let mut code = String::new();
    let mut rest = text;
    while let Some(a) = rest.find("/*") {
        code.push_str(&rest[..a]);
        rest = &rest[a + rest[a..].find("*/").unwrap() + 2..];
    }
    code.push_str(rest);
    let code: String = code
        .lines()
        .filter(|l| !l.trim_start().starts_with('#'))
        .collect::<Vec<_>>()
        .join(" ");
    let mut out = Vec::new();
    for stmt in code.split(';') {
        let s = stmt.split_whitespace().collect::<Vec<_>>().join(" ");
        if !s.contains("pf_dem_") || s.contains("typedef") || !s.ends_with(')') {
            continue;
        }
        let head = &s[..s.find('(').unwrap()];
        let name = head.rsplit([' ', '*']).next().unwrap();
        if !name.starts_with("pf_dem_") {
            continue;
        }
        let ret = head[..head.len() - name.len()].trim();
        let args = &s[s.find('(').unwrap() + 1..s.len() - 1];
        let params: Vec<String> = if args.trim() == "void" {
            Vec::new()
        } else {
            args.split(',')
                .map(|a| {
                    let a = a.trim();
                    // Drop the parameter name (the last identifier).
                    let cut = a.rfind([' ', '*']).unwrap();
                    rust_type(&a[..=cut])
                })
                .collect()
        };
        let ret = rust_type(ret);
        let sig = format!(
            "unsafe extern \"C\" fn({}){}",
            params.join(", "),
            if ret == "()" {
                String::new()
            } else {
                format!(" -> {ret}")
            }
        );
        out.push((name.to_string(), sig));
    }
    out
}

fn strip_paths(t: &str) -> String {
    t.replace("plugflow_coupling::abi::", "")
}

#[test]
fn header_and_rust_declarations_agree() {
    let text = header();
    let protos = header_prototypes(&text);
    let decls = abi::declarations();
    assert_eq!(
        protos.len(),
        decls.len(),
        "header has {:?}",
        protos.iter().map(|p| &p.0).collect::<Vec<_>>()
    );
    for (name, ty, _) in decls {
        let (_, sig) = protos
            .iter()
            .find(|(n, _)| n == name)
            .unwrap_or_else(|| panic!("`{name}` missing from the header"));
        assert_eq!(sig, &strip_paths(ty), "prototype of `{name}`");
    }
    let define = |name: &str| -> i64 {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("#define {name} ")))
            .unwrap_or_else(|| panic!("#define {name} missing"));
        line.split_whitespace().nth(2).unwrap().parse().unwrap()
    };
    assert_eq!(define("PF_DEM_ABI_MAJOR"), abi::ABI_MAJOR as i64);
    assert_eq!(define("PF_DEM_ABI_MINOR"), abi::ABI_MINOR as i64);
    use abi::status::*;
    for (n, v) in [
        ("PF_OK", OK),
        ("PF_ERR_NULL", NULL),
        ("PF_ERR_INVALID_ARGUMENT", INVALID_ARGUMENT),
        ("PF_ERR_SCENE", SCENE),
        ("PF_ERR_NON_FINITE", NON_FINITE),
        ("PF_ERR_ENGINE", ENGINE),
        ("PF_ERR_BUFFER_TOO_SMALL", BUFFER_TOO_SMALL),
        ("PF_ERR_PANIC", PANIC),
        ("PF_ERR_UNSUPPORTED", UNSUPPORTED),
    ] {
        assert_eq!(define(n), v as i64, "{n}");
    }
    // Struct layouts as the C compiler lays them out.
    let dir = scratch("layout");
    let c = dir.join("layout.c");
    std::fs::write(
        &c,
        r#"#include <stddef.h>
#include <stdio.h>
#include "plugflow_dem.h"
int main(void) {
  printf("%zu %zu %zu %zu %zu %zu %zu\n", sizeof(pf_dem_info), offsetof(pf_dem_info, step_count),
         offsetof(pf_dem_info, wall_count), offsetof(pf_dem_info, name), offsetof(pf_dem_info, version),
         sizeof(pf_dem_flow), offsetof(pf_dem_flow, lost_count));
  return 0;
}
"#,
    )
    .unwrap();
    let exe = dir.join("layout");
    compile(&[c.as_path()], &exe, &[]);
    let out = Command::new(&exe).output().unwrap();
    let got = String::from_utf8_lossy(&out.stdout).trim().to_string();
    let want = format!(
        "{} {} {} {} {} {} {}",
        std::mem::size_of::<PfDemInfo>(),
        std::mem::offset_of!(PfDemInfo, step_count),
        std::mem::offset_of!(PfDemInfo, wall_count),
        std::mem::offset_of!(PfDemInfo, name),
        std::mem::offset_of!(PfDemInfo, version),
        std::mem::size_of::<PfDemFlow>(),
        std::mem::offset_of!(PfDemFlow, lost_count),
    );
    assert_eq!(got, want, "struct layouts (C vs Rust)");
}

fn compile(sources: &[&Path], exe: &Path, extra: &[&str]) {
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let out = Command::new(&cc)
        .args([
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-pedantic",
            "-O1",
        ])
        .arg("-I")
        .arg(root().join("bindings/include"))
        .args(sources)
        .arg("-o")
        .arg(exe)
        .args(extra)
        .output()
        .unwrap_or_else(|e| panic!("cannot run the C compiler `{cc}`: {e}"));
    assert!(
        out.status.success(),
        "C compile failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The scene of the C program: paper grains fed into the tube without gas (a handful of
/// collisions with the cap and each other within the steps run).
fn dry_scene() -> Scene {
    Scene::load(
        &root().join("cases/vertical_dry_feed.toml"),
        &["dem.threads=1".to_string()],
    )
    .unwrap()
}

#[test]
fn c_program_through_the_header_matches_the_engine_bit_for_bit() {
    let dir = scratch("c");
    let exe = dir.join("abi_check");
    let lib = library();
    let libdir = lib.parent().unwrap().display().to_string();
    compile(
        &[&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/abi_check.c")],
        &exe,
        &[
            &format!("-L{libdir}"),
            "-lplugflow_dem_native",
            &format!("-Wl,-rpath,{libdir}"),
        ],
    );
    let scene = dry_scene();
    let json = dir.join("scene.json");
    std::fs::write(&json, scene.to_json()).unwrap();
    let steps = 30_000u64;
    let out = Command::new(&exe)
        .arg(&json)
        .arg(steps.to_string())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "abi_check failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    let mut lines = text.lines();
    let head = lines.next().unwrap().to_string();

    // The same sequence, directly.
    let mut dem = NativeDem::new(plugflow::setup::dem_config(&scene).unwrap()).unwrap();
    let mut done = 0;
    while done < steps {
        dem.advance(100).unwrap();
        let f = vec![[0.0, 0.0, 1e-6]; dem.state.len()];
        dem.set_fluid_forces(&f, None).unwrap();
        dem.remove_past_outlet().unwrap();
        done += 100;
    }
    let p = dem.particles();
    assert_eq!(
        head,
        format!(
            "steps {} grains {} fed {}",
            dem.step_count(),
            p.len(),
            dem.flow.fed_count
        )
    );
    assert!(p.len() > 10, "too few grains to mean anything: {}", p.len());
    for (i, line) in lines.enumerate() {
        let w: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(w[0].parse::<u64>().unwrap(), p.id[i]);
        for d in 0..3 {
            let bits = u64::from_str_radix(w[1 + d], 16).unwrap();
            assert_eq!(
                bits,
                p.position[i][d].to_bits(),
                "grain {} axis {d}: C {} vs direct {}",
                p.id[i],
                f64::from_bits(bits),
                p.position[i][d]
            );
        }
    }
}

#[test]
fn coupled_run_through_the_loader_matches_the_direct_engine_bit_for_bit() {
    let scene = Scene::load(
        &root().join("cases/vertical_plug.toml"),
        &["dem.threads=2".to_string()],
    )
    .unwrap();
    let cfg = plugflow::setup::dem_config(&scene).unwrap();
    let mut direct = NativeDem::new(cfg.clone()).unwrap();
    let mut via_abi = AbiBackend::load(&library(), &scene.to_json()).unwrap();
    assert_eq!(via_abi.engine_name(), "native");
    assert_eq!(via_abi.time_step(), direct.time_step());
    let mut gas_a = coupling_from_scene(&scene, &cfg).unwrap().unwrap();
    let mut gas_b = coupling_from_scene(&scene, &cfg).unwrap().unwrap();
    // 0.3 s: the inlet feeds ~150 grains that settle on the cap under gas drag.
    let exchanges = (0.3 / gas_a.interval).round() as u64;
    for _ in 0..exchanges {
        direct.advance(gas_a.substeps).unwrap();
        gas_a.exchange(&mut direct).unwrap();
        via_abi.advance(gas_b.substeps).unwrap();
        gas_b.exchange(&mut via_abi).unwrap();
    }
    let (a, b) = (direct.particles(), via_abi.particles());
    assert!(a.len() > 100, "{} grains", a.len());
    assert_eq!(a.id, b.id);
    for i in 0..a.len() {
        for d in 0..3 {
            assert_eq!(a.position[i][d].to_bits(), b.position[i][d].to_bits());
            assert_eq!(a.velocity[i][d].to_bits(), b.velocity[i][d].to_bits());
        }
    }
    assert_eq!(
        gas_a.pressure_drop().to_bits(),
        gas_b.pressure_drop().to_bits()
    );
    assert!(gas_a.pressure_drop() > 0.0);
    let flow = via_abi.flow().unwrap();
    assert_eq!(flow.fed_count, direct.flow.fed_count);
    let walls = via_abi.wall_forces();
    assert_eq!(walls, direct.wall_forces());
}

/// ABI 1.3: the state `pf_dem_save_state` hands out, given to `pf_dem_restore_state` of a
/// second engine built from the same scene, goes on bit for bit as the first engine does
/// (the built-in engine's checkpoints through the C ABI); bytes that are not such a state
/// are refused with a status and a message, not a crash.
#[test]
fn saved_state_through_the_abi_goes_on_bit_for_bit() {
    let scene = dry_scene();
    let mut a = AbiBackend::load(&library(), &scene.to_json()).unwrap();
    a.advance(20_000).unwrap();
    assert!(!a.particles().is_empty());
    let state = a.save_state().unwrap();
    let mut b = AbiBackend::load(&library(), &scene.to_json()).unwrap();
    b.restore_state(&state).unwrap();
    a.advance(5_000).unwrap();
    b.advance(5_000).unwrap();
    let (pa, pb) = (a.particles(), b.particles());
    assert_eq!(pa.id, pb.id);
    let bits = |v: &[[f64; 3]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(pa.position), bits(pb.position));
    assert_eq!(bits(pa.velocity), bits(pb.velocity));
    assert_eq!(bits(pa.angular_velocity), bits(pb.angular_velocity));
    assert_eq!(a.step_count(), b.step_count());
    assert_eq!(a.flow(), b.flow());
    let mut c = AbiBackend::load(&library(), &scene.to_json()).unwrap();
    let err = c.restore_state(b"not a state").unwrap_err().to_string();
    assert!(err.contains("pf_dem_restore_state"), "{err}");
}

/// A library built from C text.
fn c_library(dir: &Path, name: &str, body: &str) -> PathBuf {
    let src = dir.join(format!("{name}.c"));
    std::fs::write(&src, body).unwrap();
    let lib = dir.join(format!("lib{name}.so"));
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let out = Command::new(cc)
        .args(["-shared", "-fPIC", "-o"])
        .arg(&lib)
        .arg(&src)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    lib
}

#[test]
fn loader_refuses_another_major_and_missing_calls() {
    let dir = scratch("loader");
    let future = c_library(
        &dir,
        "future",
        "unsigned pf_dem_abi_version(void) { return (2u << 16) | 3u; }\n",
    );
    match AbiBackend::load(&future, "{}") {
        Err(LoadError::Version {
            major: 2, minor: 3, ..
        }) => {}
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("a major-2 library was accepted"),
    }
    let partial = c_library(
        &dir,
        "partial",
        "unsigned pf_dem_abi_version(void) { return 1u << 16; }\nint pf_dem_create(void) { return 0; }\n",
    );
    match AbiBackend::load(&partial, "{}") {
        Err(e @ LoadError::Missing { .. }) => {
            assert!(e.to_string().contains("pf_dem_destroy"), "{e}")
        }
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("a library without pf_dem_destroy was accepted"),
    }
    match AbiBackend::load(&dir.join("libnothing.so"), "{}") {
        Err(LoadError::Open { .. }) => {}
        _ => panic!("a missing library loaded"),
    }
    // A scene the engine refuses comes back as the engine's words, naming the field.
    match AbiBackend::load(&library(), r#"{"schema_version": 1}"#) {
        Err(e @ LoadError::Create { .. }) => assert!(e.to_string().contains("name"), "{e}"),
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("an empty scene was accepted"),
    }
}

/// `pf_dem_check` (ABI 1.1): a scene the engine takes is accepted, one it refuses comes back
/// with the engine's words naming the field, and a 1.0 library without the call says so.
#[test]
fn check_answers_without_starting_the_engine() {
    use plugflow_coupling::abi::{check_scene, CheckOutcome};
    let case = root().join("cases/vertical_plug.toml");
    let good = Scene::load(&case, &[]).unwrap();
    assert_eq!(
        check_scene(&library(), &good.to_json()).unwrap(),
        CheckOutcome::Accepted
    );
    // More initial grains than fit the stretch: only the engine's placement finds it.
    let crowded = Scene::load(
        &case,
        &["initial={count=5000, from=\"0 m\", to=\"0.01 m\"}".to_string()],
    )
    .unwrap();
    match check_scene(&library(), &crowded.to_json()).unwrap() {
        CheckOutcome::Refused(why) => assert!(why.contains("initial.count"), "{why}"),
        other => panic!("a crowded fill was not refused: {other:?}"),
    }
    let dir = scratch("check");
    let old = c_library(
        &dir,
        "old",
        "unsigned pf_dem_abi_version(void) { return 1u << 16; }\n",
    );
    assert_eq!(
        check_scene(&old, &good.to_json()).unwrap(),
        CheckOutcome::NotOffered
    );
}
