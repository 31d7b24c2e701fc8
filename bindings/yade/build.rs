//! With the `yade` feature: check that Debian's Python 3.11 and YADE are installed, so a
//! missing package is named at build time rather than as a link or import error.
fn main() {
    println!("cargo:rerun-if-changed=src/driver.py");
    if std::env::var_os("CARGO_FEATURE_YADE").is_none() {
        return;
    }
    for (path, what) in [
        ("/usr/include/python3.11/Python.h", "libpython3.11-dev"),
        (
            "/usr/lib/x86_64-linux-gnu/yade-double/py/yade",
            "yade python3-yade",
        ),
    ] {
        if !std::path::Path::new(path).exists() {
            panic!(
                "the `yade` feature needs {path}: run `bash scripts/setup-system.sh` \
                 (apt-get install {what})"
            );
        }
    }
}
