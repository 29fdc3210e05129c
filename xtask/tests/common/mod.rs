//! Helpers shared by the CLI tests.

use std::process::Command;

/// The built xtask binary, with `CI` set so that progress bars stay hidden.
pub fn xtask() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_xtask"));
    c.env("CI", "1");
    c
}
