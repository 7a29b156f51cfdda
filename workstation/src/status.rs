//! `workstation status`: what this build contains, for a first look.

/// Print the capabilities of this build and the next command to try.
pub fn print() {
    println!("workstation {}", env!("CARGO_PKG_VERSION"));
    println!("wire protocol version {}", protocol::PROTOCOL_VERSION);
    println!(
        "in-process demo server (feature `demo-server`): {}",
        if cfg!(feature = "demo-server") {
            "built in"
        } else {
            "not built: give `demo --server ADDR --cert FILE`"
        }
    );
    println!("try: workstation demo            (the networked demo on a fake device)");
    println!("     workstation view            (the window; the mouse is the stylus)");
    println!("     workstation view MODEL      (sculpt your own .ply .obj .off .stl .xyz)");
    println!("     workstation run --help      (against a haptics server)");
    println!("commands: run `workstation --help`");
}
