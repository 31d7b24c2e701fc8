//! `timeseries.csv`: the sampled series one row per sample, with a header, for a
//! spreadsheet or `tail -f` on a batch run. Each row is flushed as it is taken (the file of
//! a killed run holds every sample to then). Numbers are written in Rust's shortest form
//! that reads back to the same f64 (the outputs test compares them with `run.h5` bit for
//! bit). Columns a scene does not have (Δp without gas) are left out, not written as 0.

use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::Path;

use super::{OutputError, RunOutput, Sample};
use crate::Real;

/// Streams the samples into `timeseries.csv`.
pub struct CsvOutput {
    path: String,
    file: BufWriter<File>,
    gas: bool,
    walls: usize,
}

impl CsvOutput {
    /// The file with its header: time, grains in the tube, the pressure drop (gas scenes),
    /// plugs first seen, and the three force components on each wall the engine reports.
    pub fn create(path: &Path, gas: bool, walls: &[String]) -> Result<Self, OutputError> {
        let shown = path.display().to_string();
        let file = File::create(path).map_err(|e| OutputError::new(&shown, e))?;
        let mut header = vec!["time_s".to_string(), "grains_in_tube".to_string()];
        if gas {
            header.push("pressure_drop_pa_per_m".to_string());
        }
        header.push("new_plugs".to_string());
        for w in walls {
            for c in ["x", "y", "z"] {
                header.push(quoted(&format!("wall_{w}_f{c}_n")));
            }
        }
        let mut me = Self {
            path: shown,
            file: BufWriter::new(file),
            gas,
            walls: walls.len(),
        };
        me.line(&header.join(","))?;
        Ok(me)
    }

    /// The file of a run resumed from a checkpoint, cut back to its header and the first
    /// `samples` rows (what the run had written at the checkpoint), to go on appending.
    pub fn reopen(
        path: &Path,
        gas: bool,
        walls: &[String],
        samples: u64,
    ) -> Result<Self, OutputError> {
        let shown = path.display().to_string();
        let fail = |e: std::io::Error| OutputError::new(&shown, e);
        let text = std::fs::read(path).map_err(fail)?;
        let lines = 1 + samples as usize;
        let ends: Vec<usize> = text
            .iter()
            .enumerate()
            .filter(|(_, &b)| b == b'\n')
            .map(|(k, _)| k + 1)
            .take(lines)
            .collect();
        if ends.len() < lines {
            return Err(OutputError::new(
                &shown,
                format!(
                    "holds {} rows, the checkpoint was taken after {samples}",
                    ends.len().saturating_sub(1)
                ),
            ));
        }
        let file = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(fail)?;
        file.set_len(ends[lines - 1] as u64).map_err(fail)?;
        let mut file = BufWriter::new(file);
        file.seek(std::io::SeekFrom::End(0)).map_err(fail)?;
        Ok(Self {
            path: shown,
            file,
            gas,
            walls: walls.len(),
        })
    }

    fn line(&mut self, text: &str) -> Result<(), OutputError> {
        writeln!(self.file, "{text}")
            .and_then(|_| self.file.flush())
            .map_err(|e| OutputError::new(&self.path, e))
    }
}

impl RunOutput for CsvOutput {
    fn sample(&mut self, s: &Sample) -> Result<(), OutputError> {
        let mut row = vec![num(s.time), s.particles_in_tube.to_string()];
        if self.gas {
            // A gas scene always has a pressure drop; NaN (never 0) if one ever lacked it.
            row.push(num(s.pressure_drop.unwrap_or(Real::NAN)));
        }
        row.push(s.new_plugs.len().to_string());
        for k in 0..self.walls {
            let f = s.wall_forces.get(k).copied().unwrap_or([Real::NAN; 3]);
            row.extend(f.iter().map(|&v| num(v)));
        }
        self.line(&row.join(","))
    }
}

/// A header field as RFC 4180 has it: quoted (quotes doubled) when it holds a comma, a
/// quote or a line break (a wall a user named `inlet, left`), as is otherwise.
fn quoted(field: &str) -> String {
    if field.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", field.replace('"', "\"\""))
    } else {
        field.to_string()
    }
}

/// Shortest text that parses back to the same f64 (`{}` of f64 is round-trip exact).
fn num(v: Real) -> String {
    format!("{v}")
}

#[cfg(test)]
mod tests {
    /// Python's csv module (and any RFC 4180 reader) reads these back as one field each.
    #[test]
    fn header_fields_with_commas_or_quotes_are_quoted() {
        assert_eq!(super::quoted("wall_tube_fx_n"), "wall_tube_fx_n");
        assert_eq!(super::quoted("wall_a,b_fx_n"), "\"wall_a,b_fx_n\"");
        assert_eq!(
            super::quoted("wall_say \"hi\"_fx_n"),
            "\"wall_say \"\"hi\"\"_fx_n\""
        );
    }
}
