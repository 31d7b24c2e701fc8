//! Run outputs read back: run.h5 (from Rust and, where h5py is installed, from Python), the
//! ParaView files (VTK XML) read by VTK's own readers, and a run killed mid-way leaving a
//! readable run.h5.

use std::path::{Path, PathBuf};
use std::process::Command;

use plugflow::run::{run, RunOptions};
use plugflow::scene::Scene;

/// The Python that reads the outputs back: `PLUGFLOW_PYTHON`, else Debian's own (where the
/// set-up script installs h5py and VTK from Debian's packages), else `python3` on PATH.
fn python() -> Command {
    let exe = std::env::var("PLUGFLOW_PYTHON").unwrap_or_else(|_| {
        if std::path::Path::new("/usr/bin/python3").exists() {
            "/usr/bin/python3".to_string()
        } else {
            "python3".to_string()
        }
    });
    Command::new(exe)
}

fn case(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("cases")
        .join(name)
}

/// One test at a time: a test that spawns a child process (pvbatch, Python, plugflow)
/// while another test's run holds its `run.h5` open hands the child that file's descriptor,
/// and with it HDF5's lock on the file, which then cannot be opened again until the child
/// ends ("unable to lock file"). Runs of `plugflow` never spawn while writing.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|p| p.into_inner())
}

fn tmp(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("plugflow-out-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

const SNAPSHOTS: &str = r#"output.snapshots={interval="0.1 s", formats=["hdf5","vtk"]}"#;

/// The coupled vertical case for 0.3 s with snapshots every 0.1 s.
fn short_coupled_run(out: &Path) -> serde_json::Value {
    let scene = Scene::load(
        &case("vertical_plug.toml"),
        &[
            SNAPSHOTS.to_string(),
            "output.settling_time=0.1 s".to_string(),
        ],
    )
    .unwrap();
    let opts = RunOptions {
        out_dir: Some(out.to_path_buf()),
        duration: Some(0.3),
        ..RunOptions::default()
    };
    serde_json::to_value(run(&scene, &opts).unwrap().summary).unwrap()
}

/// What VTK's own readers (ParaView's, under `pvbatch`) see in the snapshot
/// files: the particles' points, ids and TIME of `particles_000002.vtp`, the gas grid's
/// dimensions, pressure and TIME of `gas_000002.vts`, the times and files of both `.pvd`
/// series, and the polygons of `geometry.vtp`. None where ParaView's Python is missing.
fn read_with_vtk(out: &Path) -> Option<serde_json::Value> {
    let script = format!(
        r#"
import json, xml.etree.ElementTree as ET
from vtkmodules.vtkIOXML import vtkXMLPolyDataReader, vtkXMLStructuredGridReader
from vtkmodules.util.numpy_support import vtk_to_numpy as np_
d = r'{}'
def read(cls, f):
    r = cls(); r.SetFileName(d + '/' + f); r.Update(); return r.GetOutput()
p = read(vtkXMLPolyDataReader, 'particles_000002.vtp')
g = read(vtkXMLStructuredGridReader, 'gas_000002.vts')
geo = read(vtkXMLPolyDataReader, 'geometry.vtp')
series = lambda f: [(float(e.get('timestep')), e.get('file')) for e in ET.parse(d + '/' + f).getroot().iter('DataSet')]
print(json.dumps(dict(
    points=np_(p.GetPoints().GetData()).tolist(),
    ids=np_(p.GetPointData().GetArray('id')).tolist(),
    velocity_components=p.GetPointData().GetArray('velocity').GetNumberOfComponents(),
    time=float(np_(p.GetFieldData().GetArray('TIME'))[0]),
    gas_dims=[g.GetExtent()[2*k+1] - g.GetExtent()[2*k] + 1 for k in range(3)],
    gas_pressure=np_(g.GetPointData().GetArray('pressure')).tolist(),
    gas_porosity_max=float(np_(g.GetPointData().GetArray('porosity')).max()),
    gas_time=float(np_(g.GetFieldData().GetArray('TIME'))[0]),
    particle_series=series('particles.pvd'),
    gas_series=series('gas.pvd'),
    geometry_polys=geo.GetNumberOfPolys(),
)))
"#,
        out.display()
    );
    pvbatch(out, "read_vtk.py", &script)
}

/// Run `script` (written into `out` as `name`) with ParaView's `pvbatch` and parse the
/// JSON line it prints; None where ParaView's Python (Debian's python3-paraview) is missing.
fn pvbatch(out: &Path, name: &str, script: &str) -> Option<serde_json::Value> {
    let script_file = out.join(name);
    std::fs::write(&script_file, script).unwrap();
    let o = Command::new("pvbatch")
        .arg("--force-offscreen-rendering")
        .arg(&script_file)
        .output()
        .ok()?;
    let text = String::from_utf8_lossy(&o.stdout).to_string();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    if !o.status.success()
        && (err.contains("No module named 'paraview'")
            || err.contains("No module named 'vtkmodules'"))
    {
        return None;
    }
    assert!(o.status.success(), "{err}");
    let json = text.lines().rfind(|l| l.starts_with('{')).unwrap_or("{}");
    Some(serde_json::from_str(json).unwrap())
}

#[test]
fn run_h5_holds_the_run_and_vtk_matches_it() {
    let _serial = serial();
    let out = tmp("h5");
    let summary = short_coupled_run(&out);
    let f = hdf5::File::open(out.join("run.h5")).unwrap();
    let scene_attr: hdf5::types::VarLenUnicode = f.attr("scene").unwrap().read_scalar().unwrap();
    assert!(scene_attr.as_str().contains("vertical_plug"));
    let time: Vec<f64> = f.dataset("time").unwrap().read_raw().unwrap();
    // 0.3 s sampled every 0.01 s.
    assert_eq!(time.len(), 30, "{time:?}");
    assert!(time.windows(2).all(|w| w[1] > w[0]));
    let por = f.dataset("fields/porosity").unwrap();
    let z = f
        .dataset("fields/z_slices")
        .unwrap()
        .read_raw::<f64>()
        .unwrap();
    assert_eq!(por.shape(), vec![30, z.len()]);
    let por: Vec<f64> = por.read_raw().unwrap();
    assert!(por.iter().all(|p| (0.0..=1.0).contains(p)));
    let p = f.dataset("fields/pressure").unwrap();
    let zg = f
        .dataset("fields/z_gas")
        .unwrap()
        .read_raw::<f64>()
        .unwrap();
    assert_eq!(p.shape(), vec![30, zg.len()]);
    // The summary's mean pressure drop is the mean of the trace after the settling time:
    // same numbers, summed in the same order, so equal to rounding.
    let dp: Vec<f64> = f.dataset("pressure_drop").unwrap().read_raw().unwrap();
    let kept: Vec<f64> = time
        .iter()
        .zip(&dp)
        .filter(|(t, _)| **t >= 0.1 - 1e-9)
        .map(|(_, d)| *d)
        .collect();
    let mean = kept.iter().sum::<f64>() / kept.len() as f64 / 100.0;
    let reported = summary["pressure_drop_hpa_per_m"].as_f64().unwrap();
    assert!(
        (mean - reported).abs() <= 1e-9 * reported.abs().max(1e-9),
        "trace mean {mean} vs summary {reported}"
    );
    // Snapshots at 0, 0.1, 0.2 s in both formats; the last one agrees bit for bit.
    timeseries_csv_is_run_h5s(&out, &f);
    let snaps = f.group("particles").unwrap().member_names().unwrap();
    assert_eq!(snaps.len(), 3, "{snaps:?}");
    let last = f.group("particles/000002").unwrap();
    let t: f64 = last.attr("time").unwrap().read_scalar().unwrap();
    let pos = last.dataset("position").unwrap().read_2d::<f64>().unwrap();
    let ids: Vec<u64> = last.dataset("id").unwrap().read_raw().unwrap();
    assert!(!ids.is_empty());
    // The ParaView files, read by VTK itself (ParaView's). test-all.sh installs ParaView's
    // Python and sets PLUGFLOW_REQUIRE_PARAVIEW=1; elsewhere the check runs only where it
    // imports.
    match read_with_vtk(&out) {
        None => {
            assert!(
                std::env::var("PLUGFLOW_REQUIRE_PARAVIEW").is_err(),
                "ParaView's Python is required here but does not import"
            );
            eprintln!("ParaView's Python not installed: the ParaView files were not read back");
        }
        Some(v) => {
            assert_eq!(v["time"].as_f64().unwrap(), t);
            assert_eq!(v["gas_time"].as_f64().unwrap(), t);
            let vids: Vec<u64> = u64s(&v["ids"]);
            assert_eq!(vids, ids);
            assert_points(&v["points"], &pos);
            assert_eq!(v["velocity_components"], 3);
            // The series carry the snapshots' simulated times (run.h5's), in order, one
            // file each (the .pvd writes them as {:e}: shortest round trip, exact).
            let snapshot_times: Vec<f64> = (0..3)
                .map(|k| {
                    f.group(&format!("particles/{k:06}"))
                        .unwrap()
                        .attr("time")
                        .unwrap()
                        .read_scalar()
                        .unwrap()
                })
                .collect();
            for (key, prefix) in [("particle_series", "particles_"), ("gas_series", "gas_")] {
                let series = v[key].as_array().unwrap();
                assert_eq!(series.len(), 3, "{v}");
                for (k, e) in series.iter().enumerate() {
                    assert_eq!(e[0].as_f64().unwrap(), snapshot_times[k], "{key}: {e}");
                    assert!(e[1].as_str().unwrap().starts_with(prefix), "{e}");
                }
            }
            // The gas grid: nodes across (x, y) and along (z) as the scene's grid, the
            // pressure the last sample's (cross-section means in run.h5 at the same time).
            let g = &plugflow::scene::Scene::load(&case("vertical_plug.toml"), &[])
                .unwrap()
                .file
                .gas
                .unwrap()
                .grid;
            let dims: Vec<u64> = u64s(&v["gas_dims"]);
            assert_eq!(dims, vec![g[1] as u64, g[2] as u64, g[0] as u64]);
            let pressure = v["gas_pressure"].as_array().unwrap();
            assert_eq!(pressure.len(), g[0] * g[1] * g[2]);
            assert!(pressure.iter().all(|p| p.as_f64().unwrap().is_finite()));
            assert!(v["gas_porosity_max"].as_f64().unwrap() <= 1.0);
            // The tube's 48 sides and the cap of its closed inlet end (the outlet is open).
            assert_eq!(v["geometry_polys"], 49);
        }
    }
    assert!(out.join("plug_statistics.png").exists() || summary["plugs_observed_mid_tube"] == 0);
    assert!(out.join("pressure_drop.png").exists());
    // Profiles are written at the end, with the same numbers as the summary's.
    let rings: Vec<f64> = f
        .dataset("profiles/ring_porosity")
        .unwrap()
        .read_raw()
        .unwrap();
    let listed: Vec<f64> = f64s_or_nan(&summary["profiles"]["ring_porosity"]);
    assert_eq!(rings.len(), listed.len());
    // Drag and contact force along the plug: one value per axial bin each (the built-in
    // engine gives its grains' contact forces).
    let drag: Vec<f64> = f.dataset("profiles/drag").unwrap().read_raw().unwrap();
    let contact: Vec<f64> = f
        .dataset("profiles/particle_force")
        .unwrap()
        .read_raw()
        .unwrap();
    assert_eq!(drag.len(), contact.len());
    assert!(drag.iter().chain(&contact).all(|x| x.is_finite()));

    // From Python, as users read it. test-all.sh installs h5py and sets
    // PLUGFLOW_REQUIRE_H5PY=1; elsewhere the check runs only where h5py imports.
    let has_h5py = python()
        .args(["-c", "import h5py"])
        .status()
        .is_ok_and(|s| s.success());
    if !has_h5py {
        assert!(
            std::env::var("PLUGFLOW_REQUIRE_H5PY").is_err(),
            "h5py is required here but does not import"
        );
        eprintln!("h5py not installed: Python read-back skipped");
        return;
    }
    let script = format!(
        "import h5py\nf = h5py.File(r'{}', 'r')\nprint(f['time'].shape[0], f['fields/porosity'].shape[1], f['particles/000002/position'].shape[0], f['fields/pressure'].attrs['unit'])",
        out.join("run.h5").display()
    );
    let o = python().args(["-c", &script]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert_eq!(
        text.trim(),
        format!("30 {} {} Pa", z.len(), ids.len()),
        "h5py read {text}"
    );
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn killed_run_leaves_a_readable_run_h5() {
    let _serial = serial();
    let out = tmp("kill");
    /// Kills the run also when an assertion below fails.
    struct Killer(std::process::Child);
    impl Drop for Killer {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
    let child = Killer(
        Command::new(env!("CARGO_BIN_EXE_plugflow"))
            .args([
                "run",
                case("vertical_plug.toml").to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--quiet",
            ])
            .spawn()
            .unwrap(),
    );
    // HDF5 locks a file open for writing, so watch its size instead of opening it: once it
    // grows past its empty layout the samples are flowing; let it write for 2 s (dozens of
    // samples), then kill the run without warning.
    let h5 = out.join("run.h5");
    let start = std::time::Instant::now();
    let mut first_size = None;
    loop {
        std::thread::sleep(std::time::Duration::from_millis(100));
        if let Ok(m) = std::fs::metadata(&h5) {
            let base = *first_size.get_or_insert(m.len());
            if m.len() > base {
                break;
            }
        }
        assert!(
            start.elapsed().as_secs() < 120,
            "run.h5 did not grow in 2 minutes"
        );
    }
    std::thread::sleep(std::time::Duration::from_secs(2));
    drop(child);
    let f = hdf5::File::open(&h5).unwrap();
    let time: Vec<f64> = f.dataset("time").unwrap().read_raw().unwrap();
    let por = f.dataset("fields/gas_porosity").unwrap();
    assert!(time.len() >= 10, "only {} samples", time.len());
    assert!(por.shape()[0] >= time.len() - 1);
    assert!(time.windows(2).all(|w| w[1] > w[0]));
    let _ = std::fs::remove_dir_all(&out);
}

/// `timeseries.csv` holds run.h5's series, one row per sample, bit for bit (written in
/// Rust's shortest round-trip form), with the columns its header names.
fn timeseries_csv_is_run_h5s(out: &Path, f: &hdf5::File) {
    let text = std::fs::read_to_string(out.join("timeseries.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let column = |name: &str| -> Vec<f64> {
        let k = header.iter().position(|h| *h == name).unwrap();
        rows.iter().map(|r| r[k]).collect()
    };
    let h5 = |name: &str| -> Vec<f64> { f.dataset(name).unwrap().read_raw().unwrap() };
    assert_eq!(column("time_s"), h5("time"));
    assert_eq!(column("pressure_drop_pa_per_m"), h5("pressure_drop"));
    assert_eq!(column("grains_in_tube"), h5("particles_in_tube"));
    assert!(header.contains(&"new_plugs"), "{header:?}");
    let walls = f.group("walls").unwrap().member_names().unwrap();
    let mut wall_columns = 0;
    let split = ["tube_axial", "tube_cross_axis"];
    for w in walls.iter().filter(|w| !split.contains(&w.as_str())) {
        let series = f
            .dataset(&format!("walls/{w}"))
            .unwrap()
            .read_2d::<f64>()
            .unwrap();
        for (c, axis) in ["x", "y", "z"].iter().enumerate() {
            let col = column(&format!("wall_{w}_f{axis}_n"));
            assert_eq!(col, series.column(c).to_vec(), "wall {w} {axis}");
            wall_columns += 1;
        }
    }
    assert!(wall_columns >= 3, "{header:?}");
    assert_eq!(header.len(), 4 + wall_columns, "{header:?}");
}

/// What ParaView itself (its XDMF reader under `pvbatch`) reads from `run.xdmf`: the
/// timesteps, and at time `at` the particles' points and ids and the slices' porosity.
/// None where ParaView's Python (`paraview.simple`) is not installed.
fn read_xdmf_with_paraview(out: &Path, at: f64) -> Option<serde_json::Value> {
    let script = format!(
        r#"
import json
from paraview.simple import XDMFReader
from paraview import servermanager as sm
from vtkmodules.util.numpy_support import vtk_to_numpy as np_
r = XDMFReader(FileNames=[r'{}/run.xdmf'])
r.UpdatePipelineInformation()
times = [float(t) for t in r.TimestepValues]
r.UpdatePipeline({:?})
data = sm.Fetch(r)
blocks = {{}}
it = data.NewIterator()
it.InitTraversal()
while not it.IsDoneWithTraversal():
    name = it.GetCurrentMetaData().Get(data.NAME())
    blocks[name] = it.GetCurrentDataObject()
    it.GoToNextItem()
p = blocks['particles']
s = blocks['slices']
print(json.dumps(dict(
    times=times,
    blocks=sorted(blocks),
    points=np_(p.GetPoints().GetData()).tolist(),
    ids=np_(p.GetPointData().GetArray('id')).tolist(),
    slice_x=np_(s.GetPoints().GetData())[:, 0].tolist(),
    porosity=np_(s.GetPointData().GetArray('porosity')).tolist(),
)))
"#,
        out.display(),
        at
    );
    pvbatch(out, "read_xdmf.py", &script)
}

/// `run.xdmf` opens `run.h5` in ParaView (issue 23): its timesteps are the sample times,
/// and at the last snapshot's time ParaView's particles are run.h5's (points, ids, bit for
/// bit) and its slices carry run.h5's porosity row of that time.
#[test]
fn run_xdmf_opens_run_h5_in_paraview() {
    let _serial = serial();
    let out = tmp("xdmf");
    short_coupled_run(&out);
    let f = hdf5::File::open(out.join("run.h5")).unwrap();
    let last = f.group("particles/000002").unwrap();
    let at: f64 = last.attr("time").unwrap().read_scalar().unwrap();
    let Some(v) = read_xdmf_with_paraview(&out, at) else {
        assert!(
            std::env::var("PLUGFLOW_REQUIRE_PARAVIEW").is_err(),
            "ParaView's Python is required here but does not import"
        );
        eprintln!("pvbatch with paraview.simple not installed: run.xdmf was not read back");
        return;
    };
    let time: Vec<f64> = f.dataset("time").unwrap().read_raw().unwrap();
    let seen: Vec<f64> = f64s(&v["times"]);
    // The samples' times (the snapshots fall on samples); the last is the last sample.
    assert_eq!(seen, time, "ParaView's timesteps");
    assert_eq!(
        v["blocks"],
        serde_json::json!(["gas", "particles", "slices"])
    );
    // At the last snapshot's time: its particles, and the slices of the sample taken
    // with it.
    let pos = last.dataset("position").unwrap().read_2d::<f64>().unwrap();
    let ids: Vec<u64> = last.dataset("id").unwrap().read_raw().unwrap();
    let vids: Vec<u64> = u64s(&v["ids"]);
    assert_eq!(vids, ids);
    assert_points(&v["points"], &pos);
    let z: Vec<f64> = f.dataset("fields/z_slices").unwrap().read_raw().unwrap();
    let xs: Vec<f64> = f64s(&v["slice_x"]);
    assert_eq!(xs, z, "slices along the axis");
    let por = f
        .dataset("fields/porosity")
        .unwrap()
        .read_2d::<f64>()
        .unwrap();
    let k = time
        .iter()
        .position(|&t| t == at)
        .expect("snapshots are taken at samples");
    let row: Vec<f64> = por.row(k).to_vec();
    let seen_por: Vec<f64> = f64s(&v["porosity"]);
    assert_eq!(seen_por, row, "the porosity of the snapshot's sample");
    std::fs::remove_dir_all(&out).ok();
}

/// A JSON array of numbers (from the ParaView scripts) as a vector.
fn f64s(v: &serde_json::Value) -> Vec<f64> {
    let list = v.as_array().unwrap_or_else(|| panic!("not an array: {v}"));
    list.iter()
        .map(|x| x.as_f64().unwrap_or_else(|| panic!("not a number: {x}")))
        .collect()
}

/// As [`f64s`], `null` (JSON's NaN) read as NaN.
fn f64s_or_nan(v: &serde_json::Value) -> Vec<f64> {
    let list = v.as_array().unwrap_or_else(|| panic!("not an array: {v}"));
    list.iter()
        .map(|x| x.as_f64().unwrap_or(f64::NAN))
        .collect()
}

fn u64s(v: &serde_json::Value) -> Vec<u64> {
    let list = v.as_array().unwrap_or_else(|| panic!("not an array: {v}"));
    list.iter()
        .map(|x| x.as_u64().unwrap_or_else(|| panic!("not a count: {x}")))
        .collect()
}

/// The points ParaView read are run.h5's positions, bit for bit.
fn assert_points(points: &serde_json::Value, pos: &ndarray::Array2<f64>) {
    let points = points.as_array().expect("points");
    assert_eq!(points.len(), pos.nrows());
    for (i, p) in points.iter().enumerate() {
        for d in 0..3 {
            assert_eq!(p[d].as_f64().unwrap(), pos[[i, d]], "grain {i} axis {d}");
        }
    }
}
