//! What every bench reads from its command line (`cargo bench --bench NAME -- --flag V`).

/// The value after `--name` on the command line, when given and readable as a `T`.
pub fn flag<T: std::str::FromStr>(name: &str) -> Option<T> {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|k| args.get(k + 1))
        .and_then(|s| s.parse().ok())
}
