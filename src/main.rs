//! The `dynaclay` command-line entry point.

fn main() {
    println!("dynaclay {}", env!("CARGO_PKG_VERSION"));
}
