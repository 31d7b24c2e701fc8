//! ParaView output as VTK XML files with binary data (format `"vtk"` of
//! `[output.snapshots]`), each snapshot as:
//!
//! - `particles_NNNNNN.vtp`: PolyData, points = grain centres, point data `radius`, `id`,
//!   `velocity`, `angular_velocity`, field data `TIME` (s);
//! - `gas_NNNNNN.vts` (gas scenes): StructuredGrid of the gas nodes (nz × nx × ny, the
//!   tube frame), point data `pressure` (P − P0, Pa), `porosity` (as the gas used it),
//!   `granular_velocity` (m/s) and, with the SIMPLE gas, `gas_velocity` (interstitial, m/s);
//!
//! and the series `particles.pvd`, `gas.pvd` that carry the simulated times (ParaView shows
//! seconds, not file numbers), rewritten (write then rename) after every snapshot so that a
//! run stopped at any moment leaves valid series; `geometry.vtp` holds the tube's surface and
//! the plane walls, written once.
//!
//! Binary data is "appended raw": after `<AppendedData encoding="raw">_`, each array as a
//! UInt64 byte count followed by its little-endian bytes (header_type="UInt64"), which
//! ParaView, VTK's readers and meshio read; no compression.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use plugflow_coupling::{ParticleView, TubeGrid};

use super::{GasSnapshot, OutputError, RunOutput};
use crate::{Real, Vec3};

/// Writes the snapshot files and their series into a folder.
#[derive(Debug)]
pub struct VtkOutput {
    dir: PathBuf,
    written: usize,
    /// (time, file name) of every particle and gas snapshot, for the series.
    particles: Vec<(Real, String)>,
    gas: Vec<(Real, String)>,
}

/// One VTK XML file being assembled: the XML text with `offset` attributes into the
/// appended binary block.
struct XmlFile {
    xml: String,
    data: Vec<u8>,
}

impl XmlFile {
    fn new(kind: &str) -> Self {
        let mut xml = String::new();
        let _ = writeln!(xml, "<?xml version=\"1.0\"?>");
        let _ = writeln!(
            xml,
            "<VTKFile type=\"{kind}\" version=\"1.0\" byte_order=\"LittleEndian\" \
             header_type=\"UInt64\">"
        );
        Self {
            xml,
            data: Vec::new(),
        }
    }

    /// A DataArray of f64 with `components` per tuple.
    fn f64s(&mut self, name: &str, components: usize, values: impl Iterator<Item = Real>) {
        let bytes: Vec<u8> = values.flat_map(|v| v.to_le_bytes()).collect();
        self.array(name, "Float64", components, &bytes);
    }

    /// A DataArray of i64.
    fn i64s(&mut self, name: &str, values: impl Iterator<Item = i64>) {
        let bytes: Vec<u8> = values.flat_map(|v| v.to_le_bytes()).collect();
        self.array(name, "Int64", 1, &bytes);
    }

    fn array(&mut self, name: &str, ty: &str, components: usize, bytes: &[u8]) {
        // NumberOfTuples: field data (TIME) is read only with it. All values are 8 bytes.
        let _ = writeln!(
            self.xml,
            "<DataArray type=\"{ty}\" Name=\"{name}\" NumberOfComponents=\"{components}\" \
             NumberOfTuples=\"{}\" format=\"appended\" offset=\"{}\"/>",
            bytes.len() / (8 * components.max(1)),
            self.data.len()
        );
        self.data
            .extend_from_slice(&(bytes.len() as u64).to_le_bytes());
        self.data.extend_from_slice(bytes);
    }

    fn line(&mut self, text: &str) {
        self.xml.push_str(text);
        self.xml.push('\n');
    }

    fn bytes(mut self) -> Vec<u8> {
        self.xml.push_str("<AppendedData encoding=\"raw\">\n_");
        let mut out = self.xml.into_bytes();
        out.extend_from_slice(&self.data);
        out.extend_from_slice(b"\n</AppendedData>\n</VTKFile>\n");
        out
    }
}

/// The `.vtp` bytes of one particle snapshot.
pub fn particles_vtp(time: Real, p: &ParticleView) -> Vec<u8> {
    let n = p.len();
    let mut f = XmlFile::new("PolyData");
    f.line("<PolyData>");
    f.line("<FieldData>");
    f.f64s("TIME", 1, std::iter::once(time));
    f.line("</FieldData>");
    let _ = writeln!(
        f.xml,
        "<Piece NumberOfPoints=\"{n}\" NumberOfVerts=\"{n}\" NumberOfLines=\"0\" \
         NumberOfStrips=\"0\" NumberOfPolys=\"0\">"
    );
    f.line("<Points>");
    f.f64s("Points", 3, p.position.iter().flatten().copied());
    f.line("</Points>");
    f.line("<Verts>");
    f.i64s("connectivity", 0..n as i64);
    f.i64s("offsets", 1..=n as i64);
    f.line("</Verts>");
    f.line("<PointData Scalars=\"radius\" Vectors=\"velocity\">");
    f.f64s("radius", 1, p.radius.iter().copied());
    f.i64s("id", p.id.iter().map(|&i| i as i64));
    f.f64s("velocity", 3, p.velocity.iter().flatten().copied());
    f.f64s(
        "angular_velocity",
        3,
        p.angular_velocity.iter().flatten().copied(),
    );
    f.line("</PointData>");
    f.line("</Piece>");
    f.line("</PolyData>");
    f.bytes()
}

/// Where the gas node `n` of `g` sits, m (its cell's centre in the tube frame).
pub fn node_position(g: &TubeGrid, n: usize) -> Vec3 {
    let i = n % g.nx;
    let j = (n / g.nx) % g.ny;
    let k = n / (g.nx * g.ny);
    let s = (k as Real + 0.5) * g.dz;
    let u = -g.radius + (i as Real + 0.5) * g.dx;
    let w = -g.radius + (j as Real + 0.5) * g.dy;
    std::array::from_fn(|c| g.origin[c] + s * g.axis[c] + u * g.e1[c] + w * g.e2[c])
}

/// The `.vts` bytes of one gas snapshot: the nodes as a structured grid whose first index
/// runs across (e1), the second across (e2), the third along the axis (the tube grid's
/// node order, so the arrays are written as they are stored).
pub fn gas_vts(time: Real, gas: &GasSnapshot) -> Vec<u8> {
    let g = gas.grid;
    let extent = format!("0 {} 0 {} 0 {}", g.nx - 1, g.ny - 1, g.nz - 1);
    let mut f = XmlFile::new("StructuredGrid");
    let _ = writeln!(f.xml, "<StructuredGrid WholeExtent=\"{extent}\">");
    f.line("<FieldData>");
    f.f64s("TIME", 1, std::iter::once(time));
    f.line("</FieldData>");
    let _ = writeln!(f.xml, "<Piece Extent=\"{extent}\">");
    f.line("<Points>");
    f.f64s("Points", 3, (0..g.len()).flat_map(|n| node_position(g, n)));
    f.line("</Points>");
    f.line("<PointData Scalars=\"pressure\">");
    f.f64s("pressure", 1, gas.pressure.iter().copied());
    f.f64s("porosity", 1, gas.porosity.iter().copied());
    f.f64s(
        "granular_velocity",
        3,
        gas.granular_velocity.iter().flatten().copied(),
    );
    if let Some(u) = &gas.gas_velocity {
        f.f64s("gas_velocity", 3, u.iter().flatten().copied());
    }
    f.line("</PointData>");
    f.line("</Piece>");
    f.line("</StructuredGrid>");
    f.bytes()
}

/// The geometry: the tube's surface (a 48-sided prism, quads) and each plane wall as a
/// square of the domain's size about its point. `.vtp` bytes.
pub fn geometry_vtp(
    tube: Option<(Vec3, Vec3, Real, Real)>,
    planes: &[(Vec3, Vec3)],
    size: Real,
) -> Vec<u8> {
    let mut points: Vec<Vec3> = Vec::new();
    let mut quads: Vec<[i64; 4]> = Vec::new();
    if let Some((origin, axis, radius, length)) = tube {
        let (e1, e2) = plugflow_coupling::grid::perpendicular_basis(axis);
        const SIDES: usize = 48;
        for end in [0.0, length] {
            for k in 0..SIDES {
                let a = 2.0 * std::f64::consts::PI * k as Real / SIDES as Real;
                points.push(std::array::from_fn(|c| {
                    origin[c] + end * axis[c] + radius * (a.cos() * e1[c] + a.sin() * e2[c])
                }));
            }
        }
        for k in 0..SIDES {
            let next = (k + 1) % SIDES;
            quads.push([k, next, SIDES + next, SIDES + k].map(|i| i as i64));
        }
    }
    for (point, normal) in planes {
        let (e1, e2) = plugflow_coupling::grid::perpendicular_basis(*normal);
        let first = points.len() as i64;
        for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            points.push(std::array::from_fn(|c| {
                point[c] + 0.5 * size * (a * e1[c] + b * e2[c])
            }));
        }
        quads.push([first, first + 1, first + 2, first + 3]);
    }
    let mut f = XmlFile::new("PolyData");
    f.line("<PolyData>");
    let _ = writeln!(
        f.xml,
        "<Piece NumberOfPoints=\"{}\" NumberOfVerts=\"0\" NumberOfLines=\"0\" \
         NumberOfStrips=\"0\" NumberOfPolys=\"{}\">",
        points.len(),
        quads.len()
    );
    f.line("<Points>");
    f.f64s("Points", 3, points.iter().flatten().copied());
    f.line("</Points>");
    f.line("<Polys>");
    f.i64s("connectivity", quads.iter().flatten().copied());
    f.i64s("offsets", (1..=quads.len() as i64).map(|k| 4 * k));
    f.line("</Polys>");
    f.line("</Piece>");
    f.line("</PolyData>");
    f.bytes()
}

/// A ParaView series: each file with its simulated time.
pub fn pvd(entries: &[(Real, String)]) -> String {
    let mut s = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"1.0\" \
         byte_order=\"LittleEndian\">\n<Collection>\n",
    );
    for (t, file) in entries {
        let _ = writeln!(
            s,
            "<DataSet timestep=\"{t:e}\" part=\"0\" file=\"{file}\"/>"
        );
    }
    s.push_str("</Collection>\n</VTKFile>\n");
    s
}

/// Write `bytes` to `path` whole or not at all (a temporary file renamed over it).
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, bytes)
        .and_then(|_| std::fs::rename(&tmp, path))
        .map_err(|e| OutputError::new(path.display(), e))
}

impl VtkOutput {
    /// Snapshots go to `dir`; `geometry` is the tube (origin, axis, radius, length) and the
    /// plane walls (point, normal) with the size to draw them at, m.
    pub fn new(
        dir: &Path,
        tube: Option<(Vec3, Vec3, Real, Real)>,
        planes: &[(Vec3, Vec3)],
        size: Real,
    ) -> Result<Self, OutputError> {
        write_atomic(&dir.join("geometry.vtp"), &geometry_vtp(tube, planes, size))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            written: 0,
            particles: Vec::new(),
            gas: Vec::new(),
        })
    }

    /// The output of a scene: its tube and plane walls (drawn as squares the size of the
    /// tube's diameter, or of the box without a tube) into `geometry.vtp`.
    pub fn for_scene(dir: &Path, cfg: &crate::dem::DemConfig) -> Result<Self, OutputError> {
        use crate::dem::walls::WallShape;
        let tube = cfg.tube.map(|t| (t.origin, t.axis, t.radius, t.length));
        let planes: Vec<(Vec3, Vec3)> = cfg
            .walls
            .iter()
            .filter_map(|w| match w.shape {
                WallShape::Plane { point, normal } => Some((point, normal)),
                WallShape::Cylinder { .. } => None,
            })
            .collect();
        let size = cfg.tube.map_or_else(
            || {
                (0..3)
                    .map(|k| cfg.box_hi[k] - cfg.box_lo[k])
                    .fold(0.0, Real::max)
            },
            |t| 2.0 * t.radius,
        );
        Self::new(dir, tube, &planes, size)
    }

    /// The series of a run resumed from a checkpoint: the snapshots taken by then (at
    /// `times`) stay, later ones of the stopped run are removed, the `.pvd` files are
    /// written again for the kept ones.
    pub fn reopen(
        dir: &Path,
        cfg: &crate::dem::DemConfig,
        times: &[Real],
        gas: bool,
    ) -> Result<Self, OutputError> {
        let mut me = Self::for_scene(dir, cfg)?;
        let kept = times.len();
        let entries = std::fs::read_dir(dir).map_err(|e| OutputError::new(dir.display(), e))?;
        for entry in entries.flatten() {
            let name = entry.file_name();
            let name = name.to_string_lossy();
            let number = name
                .strip_prefix("particles_")
                .and_then(|n| n.strip_suffix(".vtp"))
                .or_else(|| {
                    name.strip_prefix("gas_")
                        .and_then(|n| n.strip_suffix(".vts"))
                });
            if number
                .and_then(|n| n.parse::<usize>().ok())
                .is_some_and(|k| k >= kept)
            {
                std::fs::remove_file(entry.path())
                    .map_err(|e| OutputError::new(entry.path().display(), e))?;
            }
        }
        for (k, &t) in times.iter().enumerate() {
            me.particles.push((t, format!("particles_{k:06}.vtp")));
            if gas {
                me.gas.push((t, format!("gas_{k:06}.vts")));
            }
        }
        me.written = kept;
        write_atomic(&dir.join("particles.pvd"), pvd(&me.particles).as_bytes())?;
        if gas {
            write_atomic(&dir.join("gas.pvd"), pvd(&me.gas).as_bytes())?;
        }
        Ok(me)
    }

    /// Snapshots written so far.
    pub fn written(&self) -> usize {
        self.written
    }
}

impl RunOutput for VtkOutput {
    fn snapshot(
        &mut self,
        time: Real,
        _step: u64,
        particles: &ParticleView,
        gas: Option<&GasSnapshot>,
    ) -> Result<(), OutputError> {
        let name = format!("particles_{:06}.vtp", self.written);
        write_atomic(&self.dir.join(&name), &particles_vtp(time, particles))?;
        self.particles.push((time, name));
        write_atomic(
            &self.dir.join("particles.pvd"),
            pvd(&self.particles).as_bytes(),
        )?;
        if let Some(g) = gas {
            let name = format!("gas_{:06}.vts", self.written);
            write_atomic(&self.dir.join(&name), &gas_vts(time, g))?;
            self.gas.push((time, name));
            write_atomic(&self.dir.join("gas.pvd"), pvd(&self.gas).as_bytes())?;
        }
        self.written += 1;
        Ok(())
    }
}
