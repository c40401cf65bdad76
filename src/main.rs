//! The `plume` command-line tool: a thin wrapper around the library.

fn main() {
    println!("plume {}", env!("CARGO_PKG_VERSION"));
}
