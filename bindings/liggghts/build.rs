//! Builds the C++ layer over LIGGGHTS and links Debian's libliggghts, only with the
//! `liggghts` feature (without it this crate is empty and needs nothing installed).
fn main() {
    println!("cargo:rerun-if-changed=src/shim.cpp");
    if std::env::var_os("CARGO_FEATURE_LIGGGHTS").is_none() {
        return;
    }
    let inc = std::path::Path::new("/usr/include/liggghts");
    if !inc.join("library.h").exists() {
        panic!(
            "the `liggghts` feature needs LIGGGHTS's headers: run `bash scripts/setup-system.sh` \
             (apt-get install liggghts libliggghts-dev libopenmpi-dev)"
        );
    }
    let mpi = [
        "/usr/lib/x86_64-linux-gnu/openmpi/include",
        "/usr/include/openmpi",
    ];
    let mut b = cc::Build::new();
    b.cpp(true)
        .file("src/shim.cpp")
        .include(inc)
        .define("OMPI_SKIP_MPICXX", "1")
        .flag_if_supported("-std=c++11");
    for m in mpi {
        if std::path::Path::new(m).join("mpi.h").exists() {
            b.include(m);
        }
    }
    b.compile("pfl_shim");
    println!("cargo:rustc-link-lib=dylib=liggghts");
    // MPI itself for the world calls (shim.cpp); libliggghts already depends on it.
    println!("cargo:rustc-link-lib=dylib=mpi");
}
