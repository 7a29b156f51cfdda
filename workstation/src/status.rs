//! `workstation status`: what this build contains, for a first look.

/// Print the capabilities of this build and the next command to try.
pub fn print() {
    println!("workstation {}", env!("CARGO_PKG_VERSION"));
    println!("wire protocol version {}", protocol::PROTOCOL_VERSION);
    println!("commands: run `workstation --help`");
}
