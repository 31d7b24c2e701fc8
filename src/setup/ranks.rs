//! Runs under an MPI launcher (`mpirun -np N plugflow run …`): one plugflow process per
//! rank, one LIGGGHTS instance over all of them. plugflow itself links no MPI: it reads
//! the launcher's environment to know its rank before anything starts (the run's files
//! are rank 0's), and refuses what cannot run on several ranks before any engine starts.

use plugflow_coupling::Ranks;

use crate::scene::{Scene, SceneError};

/// This process's rank and the rank count under an MPI launcher; one process without.
pub fn launched() -> Ranks {
    plugflow_coupling::ranks::launcher().unwrap_or(Ranks::SINGLE)
}

/// What a scene must be to run on `ranks.size` ranks: the DEM on an engine that runs
/// under MPI (LIGGGHTS) in this process, and a user's LIGGGHTS input
/// whose `processors` grid has as many cells as there are ranks.
pub fn check_ranks(scene: &Scene, ranks: Ranks) -> Result<(), SceneError> {
    if ranks.size <= 1 {
        return Ok(());
    }
    let d = &scene.file.dem;
    let n = ranks.size;
    if d.engine != "liggghts" {
        return Err(SceneError::field(
            "dem.engine",
            format!(
                "`{}` runs in one process (the built-in engine on threads: `dem.threads`), \
                 not on the {n} ranks mpirun started; under MPI use `liggghts`, or run \
                 without mpirun",
                d.engine
            ),
        ));
    }
    if d.isolate {
        return Err(SceneError::field(
            "dem.isolate",
            format!(
                "an engine in a child process cannot join the {n} ranks mpirun started; \
                 set it false under MPI"
            ),
        ));
    }
    if let Some(path) = &d.liggghts_input {
        let text = std::fs::read_to_string(path).map_err(|e| {
            SceneError::field("dem.liggghts_input", format!("cannot read `{path}`: {e}"))
        })?;
        if let Some(grid) = processors_grid(&text) {
            let cells: usize = grid.iter().product();
            if cells != n {
                return Err(SceneError::field(
                    "dem.liggghts_input",
                    format!(
                        "`processors {} {} {}` asks for {cells} ranks, mpirun started {n}",
                        grid[0], grid[1], grid[2]
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// The `processors Px Py Pz` grid of a LIGGGHTS input when all three are numbers (a `*`
/// lets LIGGGHTS choose that one).
pub fn processors_grid(input: &str) -> Option<[usize; 3]> {
    input.lines().find_map(|line| {
        let line = line.split('#').next().unwrap_or("");
        let mut words = line.split_whitespace();
        if words.next() != Some("processors") {
            return None;
        }
        let p: Vec<usize> = words.take(3).map_while(|w| w.parse().ok()).collect();
        <[usize; 3]>::try_from(p).ok()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_processors_grid_is_read_only_when_every_count_is_given() {
        assert_eq!(
            processors_grid("units si\nprocessors 2 1 1\n"),
            Some([2, 1, 1])
        );
        assert_eq!(processors_grid("processors * * 1 # auto"), None);
        assert_eq!(processors_grid("# processors 2 2 1\nrun 0"), None);
        assert_eq!(processors_grid("run 0"), None);
    }
}
