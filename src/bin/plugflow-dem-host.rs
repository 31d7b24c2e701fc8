//! `plugflow-dem-host`: runs one DEM engine library (the C ABI) in its own process for a
//! parent plugflow (`dem.isolate = true`), serving requests on stdin/stdout. An engine that
//! ends its process (LIGGGHTS on an error) then ends only this one; the parent reports it.

use std::path::Path;
use std::process::ExitCode;

use plugflow_coupling::abi::AbiBackend;
use plugflow_coupling::isolated::serve;
use plugflow_coupling::DemBackend;

fn main() -> ExitCode {
    let served = serve(|lib, json| {
        AbiBackend::load(Path::new(lib), json)
            .map(|b| Box::new(b) as Box<dyn DemBackend>)
            .map_err(|e| e.to_string())
    });
    match served {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("plugflow-dem-host: {e}");
            ExitCode::FAILURE
        }
    }
}
