//! `viewer`: the toolkit's interactive window. See the crate documentation.

use clap::Parser;

fn main() {
    let args = viewer::Args::parse();
    if let Err(e) = viewer::run(args) {
        eprintln!("viewer: {e}");
        std::process::exit(1);
    }
}
