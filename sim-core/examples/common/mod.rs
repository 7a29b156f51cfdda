//! What the diagnostic examples share: their `KEY=VALUE` arguments, reading a PLY file and a
//! `main` that prints the error and fails.
use std::process::ExitCode;

use sim_core::io::{self, Format, Loaded};

/// Each `KEY=VALUE` argument as its key and number.
pub fn key_values(args: &[String]) -> Result<Vec<(&str, f64)>, String> {
    args.iter()
        .map(|kv| {
            let (key, value) = kv
                .split_once('=')
                .ok_or(format!("{kv}: expected KEY=VALUE"))?;
            let v: f64 = value.parse().map_err(|e| format!("{kv}: {e}"))?;
            Ok((key, v))
        })
        .collect()
}

/// A PLY file's points (and faces, if any); errors name the file.
pub fn read_ply(file: &str) -> Result<Loaded, String> {
    let reader = std::fs::File::open(file).map_err(|e| format!("{file}: {e}"))?;
    io::read(reader, Format::Ply).map_err(|e| format!("{file}: {e}"))
}

/// Run `run` on the command line's arguments; on an error print `name: error` and fail.
pub fn main(name: &str, run: fn(&[String]) -> Result<(), String>) -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{name}: {e}");
            ExitCode::FAILURE
        }
    }
}
