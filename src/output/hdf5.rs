//! `run.h5`: the run's time series in HDF5, appended and flushed sample by sample so that a
//! run killed at any moment leaves a readable file. Layout (units in each dataset's `unit`
//! attribute; documented in README.md):
//!
//! ```text
//! /                      attrs: scene (TOML text), plugflow_version, engine, engine_version
//! /time                  (t)       s      sample times
//! /pressure_drop         (t)       Pa/m   P'(z₁)/(L − z₁), z₁ the first gas node [gas]
//! /particles_in_tube     (t)       1
//! /fields/z_slices       (s)       m      slice centres along the tube axis
//! /fields/porosity       (t, s)    1      exact sphere–slab porosity per slice
//! /fields/granular_velocity (t, s) m/s    volume-weighted axial grain velocity per slice
//! /fields/z_gas          (g)       m      gas node positions along the axis [gas scenes]
//! /fields/gas_porosity   (t, g)    1      deposited porosity, cross-section mean
//! /fields/pressure       (t, g)    Pa     P − P0, cross-section mean
//! /plugs/{time,track,centre,length,min_porosity,max_granular_velocity,grains,velocity}
//!                        (p)              one row per plug per frame (velocity NaN until
//!                                         the plug has been seen twice)
//! /profiles/{xi, porosity, granular_velocity, granular_temperature, wall_normal_stress,
//!           drag, particle_force, ring_r_over_d, ring_porosity, layer_height_over_d,
//!           layer_porosity_in_plugs, layer_porosity_between_plugs}   written at the end
//! /walls/<wall>         (t, 3)    N      force of the grains on each wall the engine reports
//! /walls/tube_axial, /walls/tube_cross_axis (t) N   the tube wall's force along / across
//!                                         its axis                 [scenes with a tube]
//! /particles/NNNNNN      attrs time, step; id (n), position (n,3), velocity (n,3),
//!                        angular_velocity (n,3), radius (n)   [only when the scene asks]
//! ```

use std::path::Path;

use hdf5::types::VarLenUnicode;
use hdf5::{Dataset, File, Group};
use ndarray::{s, ArrayView1, ArrayView2};
use plugflow_coupling::ParticleView;

use super::{OutputError, RunOutput, Sample};
use crate::analysis::profiles::ProfileResult;
use crate::Real;

/// Metadata written as root attributes.
#[derive(Debug, Clone)]
pub struct RunMeta<'a> {
    /// The scene file's text.
    pub scene_text: &'a str,
    /// Engine name and version.
    pub engine: &'a str,
    /// Engine version string.
    pub engine_version: &'a str,
    /// Slice centres along the axis, m (None without a tube).
    pub z_slices: Option<Vec<Real>>,
    /// Gas node positions along the axis, m (None without gas).
    pub z_gas: Option<Vec<Real>>,
    /// Whether particle snapshots go into this file.
    pub snapshots: bool,
    /// The walls the engine reports forces on, in the order of [`Sample::wall_forces`].
    pub walls: Vec<String>,
    /// The tube's axis (unit), for the tube wall's axial and cross-axis force.
    pub tube_axis: Option<crate::Vec3>,
}

/// Streams a run into `run.h5`.
pub struct Hdf5Output {
    path: String,
    rows: usize,
    time: Dataset,
    pressure_drop: Option<Dataset>,
    in_tube: Dataset,
    slice_porosity: Option<Dataset>,
    slice_velocity: Option<Dataset>,
    gas_porosity: Option<Dataset>,
    gas_pressure: Option<Dataset>,
    plugs: Option<PlugColumns>,
    particles: Option<Group>,
    snapshots: usize,
    /// One (t, 3) force series per wall, and the tube wall's (axial, cross-axis) split.
    walls: Vec<Dataset>,
    tube_split: Option<TubeSplit>,
    /// What the file holds, for its XDMF sidecar (`run.xdmf` beside it).
    layout: super::xdmf::Layout,
    /// Declared last, so dropped last: the datasets and groups are closed before the file.
    /// The other way round, a file whose close failed (a full disk) leaves its datasets
    /// half closed, and closing them then crashes inside HDF5 (H5D_close, issue 26).
    file: File,
}

/// The tube wall's force along the axis and across it, N.
struct TubeSplit {
    wall: usize,
    axis: crate::Vec3,
    axial: Dataset,
    cross_axis: Dataset,
}

struct PlugColumns {
    rows: usize,
    columns: Vec<Dataset>,
}

const PLUG_COLUMNS: [(&str, &str); 8] = [
    ("time", "s"),
    ("track", "1"),
    ("centre", "m"),
    ("length", "m"),
    ("min_porosity", "1"),
    ("max_granular_velocity", "m/s"),
    ("grains", "1"),
    ("velocity", "m/s"),
];

/// How [`Hdf5Output::lay_out`] comes by each dataset: made new, or opened in a resumed
/// run's file and cut back to the checkpoint.
enum Walk {
    Create,
    CutBack {
        /// Samples written by the checkpoint.
        rows: usize,
        /// Particle snapshots written by then.
        snapshots: usize,
        /// The checkpoint's time, s (plug rows are kept up to it).
        time: Real,
    },
}

impl Walk {
    fn rows(&self) -> usize {
        match self {
            Walk::Create => 0,
            Walk::CutBack { rows, .. } => *rows,
        }
    }

    fn group(&self, g: &Group, name: &str) -> hdf5::Result<Group> {
        match self {
            Walk::Create => g.create_group(name),
            Walk::CutBack { .. } => g.group(name),
        }
    }

    /// A growing 1-D series.
    fn series(&self, g: &Group, name: &str, unit: &str) -> hdf5::Result<Dataset> {
        match self {
            Walk::Create => {
                let d = g.new_dataset::<Real>().chunk(256).shape(0..).create(name)?;
                unit_attr(&d, unit)?;
                Ok(d)
            }
            Walk::CutBack { rows, .. } => {
                let d = g.dataset(name)?;
                d.resize(*rows)?;
                Ok(d)
            }
        }
    }

    /// A growing (time × width) field.
    fn field(&self, g: &Group, name: &str, width: usize, unit: &str) -> hdf5::Result<Dataset> {
        match self {
            Walk::Create => {
                let d = g
                    .new_dataset::<Real>()
                    .chunk((16, width.max(1)))
                    .shape((0.., width))
                    .create(name)?;
                unit_attr(&d, unit)?;
                Ok(d)
            }
            Walk::CutBack { rows, .. } => {
                let d = g.dataset(name)?;
                d.resize((*rows, width))?;
                Ok(d)
            }
        }
    }

    /// A dataset written once (a resumed file has it already).
    fn fixed(&self, g: &Group, name: &str, v: &[Real], unit: &str) -> hdf5::Result<()> {
        match self {
            Walk::Create => fixed(g, name, v, unit),
            Walk::CutBack { .. } => Ok(()),
        }
    }

    /// The plug table's columns; rows come in time order, a resumed file keeps those
    /// observed by the checkpoint.
    fn plug_columns(&self, g: &Group) -> hdf5::Result<PlugColumns> {
        let columns = match self {
            Walk::Create => PLUG_COLUMNS
                .iter()
                .map(|(n, u)| Walk::Create.series(g, n, u))
                .collect::<Result<Vec<_>, _>>()?,
            Walk::CutBack { .. } => PLUG_COLUMNS
                .iter()
                .map(|(n, _)| g.dataset(n))
                .collect::<Result<Vec<_>, _>>()?,
        };
        let rows = match self {
            Walk::Create => 0,
            Walk::CutBack { time, .. } => {
                let times: Vec<Real> = columns[0].read_raw()?;
                let kept = times.iter().take_while(|&&t| t <= *time).count();
                for c in &columns {
                    c.resize(kept)?;
                }
                kept
            }
        };
        Ok(PlugColumns { rows, columns })
    }

    /// The particle snapshots' group; a resumed file loses those after the checkpoint's,
    /// and the kept ones are listed (name, time, grains) for the XDMF sidecar.
    fn snapshots(
        &self,
        root: &Group,
        kept: &mut Vec<(String, Real, usize)>,
    ) -> hdf5::Result<Group> {
        let Walk::CutBack { snapshots, .. } = self else {
            return root.create_group("particles");
        };
        let g = root.group("particles")?;
        let mut names = g.member_names()?;
        names.sort();
        for s in names {
            if s.parse::<usize>().is_ok_and(|k| k >= *snapshots) {
                g.unlink(&s)?;
            } else {
                let snap = g.group(&s)?;
                let t: Real = snap.attr("time")?.read_scalar()?;
                let n = snap.dataset("id")?.size();
                kept.push((s, t, n));
            }
        }
        Ok(g)
    }
}

/// Strong close: dropping the writer closes the file and every object in it at once, so
/// the file is free for readers the moment the run ends.
fn strong_close(
    p: &mut hdf5::plist::file_access::FileAccessBuilder,
) -> &mut hdf5::plist::file_access::FileAccessBuilder {
    p.fclose_degree(hdf5::file::FileCloseDegree::Strong)
}

impl Hdf5Output {
    /// Create (truncate) `path` and lay out the datasets the run will fill.
    pub fn create(path: &Path, meta: &RunMeta) -> Result<Self, OutputError> {
        let name = path.display().to_string();
        let err = |e: hdf5::Error| OutputError::new(&name, e);
        let file = File::with_options()
            .with_fapl(strong_close)
            .create(path)
            .map_err(err)?;
        text_attr(&file, "scene", meta.scene_text).map_err(err)?;
        text_attr(&file, "plugflow_version", env!("CARGO_PKG_VERSION")).map_err(err)?;
        text_attr(&file, "engine", meta.engine).map_err(err)?;
        text_attr(&file, "engine_version", meta.engine_version).map_err(err)?;
        Self::lay_out(name, file, meta, Walk::Create)
    }

    /// Open the `run.h5` of a run resumed from a checkpoint and cut it back to what the
    /// run had written then: `samples` rows of every series, the plug rows observed by
    /// `time`, `snapshots` particle snapshots, no profiles (they are written at the end).
    /// The layout must be the one [`Hdf5Output::create`] makes for `meta`.
    pub fn reopen(
        path: &Path,
        meta: &RunMeta,
        samples: u64,
        snapshots: usize,
        time: Real,
    ) -> Result<Self, OutputError> {
        let name = path.display().to_string();
        let file = File::with_options()
            .with_fapl(strong_close)
            .open_rw(path)
            .map_err(|e| OutputError::new(&name, e))?;
        let rows = samples as usize;
        let held = file.dataset("time").map(|d| d.size()).unwrap_or(0);
        if held < rows {
            return Err(OutputError::new(
                &name,
                format!("holds {held} samples, the checkpoint was taken after {rows}"),
            ));
        }
        let walk = Walk::CutBack {
            rows,
            snapshots,
            time,
        };
        Self::lay_out(name, file, meta, walk)
    }

    /// The file's datasets for `meta`, made or (resumed) opened and cut back: one walk
    /// over the layout, so that a resumed file is the one a new run makes.
    fn lay_out(name: String, file: File, meta: &RunMeta, walk: Walk) -> Result<Self, OutputError> {
        let err = |e: hdf5::Error| OutputError::new(&name, e);
        let root: &Group = &file;
        let time = walk.series(root, "time", "s").map_err(err)?;
        let in_tube = walk.series(root, "particles_in_tube", "1").map_err(err)?;
        let pressure_drop = match meta.z_gas {
            Some(_) => Some(walk.series(root, "pressure_drop", "Pa/m").map_err(err)?),
            None => None,
        };
        let fields = walk.group(root, "fields").map_err(err)?;
        let (mut slice_porosity, mut slice_velocity, mut plugs) = (None, None, None);
        if let Some(z) = &meta.z_slices {
            walk.fixed(&fields, "z_slices", z, "m").map_err(err)?;
            slice_porosity = Some(walk.field(&fields, "porosity", z.len(), "1").map_err(err)?);
            slice_velocity = Some(
                walk.field(&fields, "granular_velocity", z.len(), "m/s")
                    .map_err(err)?,
            );
            let g = walk.group(root, "plugs").map_err(err)?;
            plugs = Some(walk.plug_columns(&g).map_err(err)?);
        }
        let (mut gas_porosity, mut gas_pressure) = (None, None);
        if let Some(z) = &meta.z_gas {
            walk.fixed(&fields, "z_gas", z, "m").map_err(err)?;
            gas_porosity = Some(
                walk.field(&fields, "gas_porosity", z.len(), "1")
                    .map_err(err)?,
            );
            gas_pressure = Some(
                walk.field(&fields, "pressure", z.len(), "Pa")
                    .map_err(err)?,
            );
        }
        let wall_group = walk.group(root, "walls").map_err(err)?;
        let walls = meta
            .walls
            .iter()
            .map(|w| walk.field(&wall_group, &dataset_name(w), 3, "N"))
            .collect::<Result<Vec<_>, _>>()
            .map_err(err)?;
        let tube_split = match (meta.tube_axis, meta.walls.iter().position(|w| w == "tube")) {
            (Some(axis), Some(wall)) => Some(TubeSplit {
                wall,
                axis,
                axial: walk.series(&wall_group, "tube_axial", "N").map_err(err)?,
                cross_axis: walk
                    .series(&wall_group, "tube_cross_axis", "N")
                    .map_err(err)?,
            }),
            _ => None,
        };
        let mut layout = super::xdmf::Layout {
            times: time.read_raw().map_err(err)?,
            slices: meta.z_slices.as_ref().map(Vec::len),
            gas: meta.z_gas.as_ref().map(Vec::len),
            snapshots: Vec::new(),
        };
        let particles = match meta.snapshots {
            true => Some(walk.snapshots(root, &mut layout.snapshots).map_err(err)?),
            false => None,
        };
        if matches!(walk, Walk::CutBack { .. }) && file.link_exists("profiles") {
            file.unlink("profiles").map_err(err)?;
        }
        file.flush().map_err(err)?;
        Ok(Self {
            path: name,
            rows: walk.rows(),
            snapshots: layout.snapshots.len(),
            file,
            layout,
            time,
            pressure_drop,
            in_tube,
            slice_porosity,
            slice_velocity,
            gas_porosity,
            gas_pressure,
            plugs,
            particles,
            walls,
            tube_split,
        })
    }

    fn err(&self, e: hdf5::Error) -> OutputError {
        OutputError::new(&self.path, e)
    }

    fn append_sample(&mut self, s: &Sample) -> hdf5::Result<()> {
        let n = self.rows;
        append1(&self.time, n, s.time)?;
        append1(&self.in_tube, n, s.particles_in_tube as Real)?;
        if let Some(d) = &self.pressure_drop {
            append1(d, n, s.pressure_drop.unwrap_or(Real::NAN))?;
        }
        if let Some(f) = s.slices {
            if let Some(d) = &self.slice_porosity {
                append2(d, n, &f.porosity)?;
            }
            if let Some(d) = &self.slice_velocity {
                append2(d, n, &f.velocity)?;
            }
        }
        if let (Some(d), Some(v)) = (&self.gas_porosity, s.gas_porosity) {
            append2(d, n, v)?;
        }
        if let (Some(d), Some(v)) = (&self.gas_pressure, s.gas_pressure) {
            append2(d, n, v)?;
        }
        for (d, f) in self.walls.iter().zip(s.wall_forces) {
            append2(d, n, f)?;
        }
        if let Some(t) = &self.tube_split {
            let f = s.wall_forces.get(t.wall).copied().unwrap_or([Real::NAN; 3]);
            let (axial, cross) = axial_split(f, t.axis);
            append1(&t.axial, n, axial)?;
            append1(&t.cross_axis, n, cross)?;
        }
        if let Some(p) = self.plugs.as_mut() {
            for o in s.new_plugs {
                let row = [
                    o.time,
                    o.track as Real,
                    o.centre,
                    o.length,
                    o.min_porosity,
                    o.max_velocity,
                    o.grains,
                    o.velocity.unwrap_or(Real::NAN),
                ];
                for (c, v) in p.columns.iter().zip(row) {
                    append1(c, p.rows, v)?;
                }
                p.rows += 1;
            }
        }
        self.rows += 1;
        self.layout.times.push(s.time);
        self.file.flush()
    }

    fn write_snapshot(&mut self, time: Real, step: u64, p: &ParticleView) -> hdf5::Result<()> {
        let Some(g) = &self.particles else {
            return Ok(());
        };
        let group = format!("{:06}", self.snapshots);
        let snap = g.create_group(&group)?;
        snap.new_attr::<Real>()
            .create("time")?
            .write_scalar(&time)?;
        snap.new_attr::<u64>().create("step")?.write_scalar(&step)?;
        snap.new_dataset_builder()
            .with_data(ArrayView1::from(p.id))
            .create("id")?;
        snap.new_dataset_builder()
            .with_data(ArrayView1::from(p.radius))
            .create("radius")?;
        for (name, v) in [
            ("position", p.position),
            ("velocity", p.velocity),
            ("angular_velocity", p.angular_velocity),
        ] {
            let flat: Vec<Real> = v.iter().flatten().copied().collect();
            let a = ArrayView2::from_shape((v.len(), 3), &flat).expect("n × 3 matches");
            snap.new_dataset_builder().with_data(a).create(name)?;
        }
        self.snapshots += 1;
        self.layout.snapshots.push((group, time, p.len()));
        self.file.flush()
    }
}

impl Hdf5Output {
    fn write_profiles(&mut self, r: &ProfileResult) -> hdf5::Result<()> {
        let g = self.file.create_group("profiles")?;
        g.new_attr::<u64>()
            .create("plugs_used")?
            .write_scalar(&r.plugs_used)?;
        for (name, v, unit) in [
            ("xi", &r.xi, "m"),
            ("porosity", &r.porosity, "1"),
            ("granular_velocity", &r.velocity, "m/s"),
            ("granular_temperature", &r.temperature, "m^2/s^2"),
            ("wall_normal_stress", &r.wall_stress, "Pa"),
            ("drag", &r.drag, "N/m^3"),
            ("particle_force", &r.particle_force, "N/m^3"),
            ("ring_r_over_d", &r.ring_r_over_d, "1"),
            ("ring_porosity", &r.ring_porosity, "1"),
            ("layer_height_over_d", &r.layer_h_over_d, "1"),
            ("layer_porosity_in_plugs", &r.layer_porosity_plug, "1"),
            ("layer_porosity_between_plugs", &r.layer_porosity_gap, "1"),
        ] {
            fixed(&g, name, v, unit)?;
        }
        self.file.flush()
    }
}

impl RunOutput for Hdf5Output {
    fn close(&mut self) -> Result<(), OutputError> {
        self.file.flush().map_err(|e| self.err(e))?;
        let path = std::path::Path::new(&self.path);
        let href = path
            .file_name()
            .map_or_else(|| self.path.clone(), |n| n.to_string_lossy().into_owned());
        let text = super::xdmf::sidecar(&href, &self.layout);
        super::xdmf::write(&path.with_extension("xdmf"), &text)
    }

    fn finish(&mut self, profiles: Option<&ProfileResult>) -> Result<(), OutputError> {
        match profiles {
            Some(p) => self.write_profiles(p).map_err(|e| self.err(e)),
            None => Ok(()),
        }
    }

    fn sample(&mut self, sample: &Sample) -> Result<(), OutputError> {
        self.append_sample(sample).map_err(|e| self.err(e))
    }

    fn snapshot(
        &mut self,
        time: Real,
        step: u64,
        particles: &ParticleView,
        _gas: Option<&super::GasSnapshot>,
    ) -> Result<(), OutputError> {
        self.write_snapshot(time, step, particles)
            .map_err(|e| self.err(e))
    }
}

/// A force's part along a unit `axis` (signed) and the magnitude of the rest, N. On a tube
/// wall the first is the friction the grains exert along it (Janssen's wall support), the
/// second the net load across it (the weight of a layer resting in a horizontal pipe; ~0 in
/// a vertical one, where the radial pushes cancel).
pub fn axial_split(f: crate::Vec3, axis: crate::Vec3) -> (Real, Real) {
    let a: Real = (0..3).map(|k| f[k] * axis[k]).sum();
    let cross: Real = (0..3).map(|k| (f[k] - a * axis[k]).powi(2)).sum();
    (a, cross.sqrt())
}

/// A wall's name as an HDF5 dataset name (`/` would open a group).
fn dataset_name(wall: &str) -> String {
    wall.chars()
        .map(|c| if c == '/' || c == '.' { '_' } else { c })
        .collect()
}

fn text_attr(g: &Group, name: &str, text: &str) -> hdf5::Result<()> {
    // Scene text never holds NUL (TOML forbids it), which is all VarLenUnicode refuses.
    let v: VarLenUnicode = text
        .replace('\0', " ")
        .parse()
        .expect("NUL-free text converts");
    g.new_attr::<VarLenUnicode>().create(name)?.write_scalar(&v)
}

fn unit_attr(d: &Dataset, unit: &str) -> hdf5::Result<()> {
    let v: VarLenUnicode = unit.parse().expect("unit strings are NUL-free");
    d.new_attr::<VarLenUnicode>()
        .create("unit")?
        .write_scalar(&v)
}

fn fixed(g: &Group, name: &str, v: &[Real], unit: &str) -> hdf5::Result<()> {
    let d = g
        .new_dataset_builder()
        .with_data(ArrayView1::from(v))
        .create(name)?;
    unit_attr(&d, unit)
}

fn append1(d: &Dataset, n: usize, v: Real) -> hdf5::Result<()> {
    d.resize(n + 1)?;
    d.write_slice(&[v], s![n..n + 1])
}

fn append2(d: &Dataset, n: usize, row: &[Real]) -> hdf5::Result<()> {
    let w = row.len();
    d.resize((n + 1, w))?;
    let a = ArrayView2::from_shape((1, w), row).expect("1 × w matches");
    d.write_slice(a, s![n..n + 1, ..])
}
