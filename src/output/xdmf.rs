//! `run.xdmf`: an XDMF 2 sidecar that lets ParaView (its XDMF reader) open `run.h5`
//! directly, with the simulated times: written by the `run.h5` writer when it closes, from
//! what it wrote (also after a failure part-way, or a resumed run; not by opening the file
//! again: a child process forked meanwhile may hold HDF5's lock on it). Three temporal
//! collections, each only when the file has its data:
//!
//! - `slices`: the tube's slices as a polyline along x = distance along the tube axis (m),
//!   one grid per sample with `porosity` and `granular_velocity` (rows of
//!   `/fields/porosity`, `/fields/granular_velocity` by hyperslab);
//! - `gas`: the gas nodes' cross-section means along the axis, `gas_porosity` and
//!   `pressure` (P − P0, Pa) per sample;
//! - `particles`: each snapshot of `/particles/NNNNNN` as points with `velocity`,
//!   `angular_velocity`, `radius`, `id`, at the snapshot's time.

use std::fmt::Write as _;
use std::path::Path;

use super::OutputError;
use crate::Real;

/// What `run.h5` holds, as its writer knows it.
#[derive(Debug, Clone, Default)]
pub struct Layout {
    /// The sample times, s (one row of every series each).
    pub times: Vec<Real>,
    /// Slices along the tube (None without a tube).
    pub slices: Option<usize>,
    /// Gas nodes along the axis (None without gas).
    pub gas: Option<usize>,
    /// Each snapshot: its group name, time (s) and grain count.
    pub snapshots: Vec<(String, Real, usize)>,
}

/// The sidecar's text for a data file named `href` (relative to the sidecar).
pub fn sidecar(href: &str, l: &Layout) -> String {
    let mut x = String::from(
        "<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n\
         <Xdmf Version=\"2.0\">\n <Domain>\n",
    );
    let rows = l.times.len();
    let fields = [
        (
            "slices",
            l.slices,
            "fields/z_slices",
            [
                ("fields/porosity", "porosity"),
                ("fields/granular_velocity", "granular_velocity"),
            ],
        ),
        (
            "gas",
            l.gas,
            "fields/z_gas",
            [
                ("fields/gas_porosity", "gas_porosity"),
                ("fields/pressure", "pressure"),
            ],
        ),
    ];
    for (grid, width, axis, data) in fields {
        let Some(width) = width else {
            continue;
        };
        let zeros = vec!["0"; width].join(" ");
        let connect: Vec<String> = (0..width).map(|k| k.to_string()).collect();
        let _ = writeln!(
            x,
            "  <Grid Name=\"{grid}\" GridType=\"Collection\" CollectionType=\"Temporal\">"
        );
        for (k, t) in l.times.iter().enumerate() {
            let _ = write!(
                x,
                "   <Grid Name=\"{grid}_{k}\" GridType=\"Uniform\">\n    <Time Value=\"{t}\"/>\n    \
                 <Topology TopologyType=\"Polyline\" NumberOfElements=\"1\" \
                 NodesPerElement=\"{width}\">\n     <DataItem Dimensions=\"1 {width}\" \
                 NumberType=\"Int\" Format=\"XML\">{}</DataItem>\n    </Topology>\n    \
                 <Geometry GeometryType=\"X_Y_Z\">\n     {}\n     <DataItem Dimensions=\"{width}\" \
                 Format=\"XML\">{zeros}</DataItem>\n     <DataItem Dimensions=\"{width}\" \
                 Format=\"XML\">{zeros}</DataItem>\n    </Geometry>\n",
                connect.join(" "),
                hdf_item(href, axis, &[width], "Float"),
            );
            for (d, n) in data {
                let _ = write!(
                    x,
                    "    <Attribute Name=\"{n}\" AttributeType=\"Scalar\" Center=\"Node\">\n     \
                     <DataItem ItemType=\"HyperSlab\" Dimensions=\"1 {width}\" Type=\"HyperSlab\">\n      \
                     <DataItem Dimensions=\"3 2\" Format=\"XML\">{k} 0 1 1 1 {width}</DataItem>\n      \
                     {}\n     </DataItem>\n    </Attribute>\n",
                    hdf_item(href, d, &[rows, width], "Float"),
                );
            }
            x.push_str("   </Grid>\n");
        }
        x.push_str("  </Grid>\n");
    }
    if !l.snapshots.is_empty() {
        x.push_str(
            "  <Grid Name=\"particles\" GridType=\"Collection\" CollectionType=\"Temporal\">\n",
        );
        for (s, t, n) in &l.snapshots {
            let n = *n;
            let at = |d: &str| format!("particles/{s}/{d}");
            let _ = write!(
                x,
                "   <Grid Name=\"particles_{s}\" GridType=\"Uniform\">\n    <Time Value=\"{t}\"/>\n    \
                 <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"{n}\"/>\n    \
                 <Geometry GeometryType=\"XYZ\">\n     {}\n    </Geometry>\n",
                hdf_item(href, &at("position"), &[n, 3], "Float"),
            );
            for (d, kind, dims, ty) in [
                ("velocity", "Vector", vec![n, 3], "Float"),
                ("angular_velocity", "Vector", vec![n, 3], "Float"),
                ("radius", "Scalar", vec![n], "Float"),
                ("id", "Scalar", vec![n], "UInt"),
            ] {
                let _ = write!(
                    x,
                    "    <Attribute Name=\"{d}\" AttributeType=\"{kind}\" Center=\"Node\">\n     \
                     {}\n    </Attribute>\n",
                    hdf_item(href, &at(d), &dims, ty),
                );
            }
            x.push_str("   </Grid>\n");
        }
        x.push_str("  </Grid>\n");
    }
    x.push_str(" </Domain>\n</Xdmf>\n");
    x
}

/// Write `text` to `path` (through a temporary name: a reader never sees half of it).
pub fn write(path: &Path, text: &str) -> Result<(), OutputError> {
    let tmp = path.with_extension("xdmf.part");
    std::fs::write(&tmp, text)
        .and_then(|_| std::fs::rename(&tmp, path))
        .map_err(|e| OutputError::new(path.display(), e))
}

/// A DataItem reading dataset `path` of `href` (8-byte numbers).
fn hdf_item(href: &str, path: &str, dims: &[usize], number: &str) -> String {
    let dims: Vec<String> = dims.iter().map(|d| d.to_string()).collect();
    format!(
        "<DataItem Dimensions=\"{}\" NumberType=\"{number}\" Precision=\"8\" \
         Format=\"HDF\">{href}:/{path}</DataItem>",
        dims.join(" ")
    )
}
