//! What the diagnostic examples share: their `KEY=VALUE` arguments, reading a PLY file and a
//! `main` that prints the error and fails. Each example compiles its own copy and uses a part.
#![allow(dead_code)]
use std::process::ExitCode;

use sim_core::io::{self, Format, Loaded};
use sim_core::reconstruct::{IgnoreStages, NormalPolicy, Reconstruction, reconstruct};
use sim_core::{FitParams, NoProgress, PointSet};

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

/// `base` with the [`FitParams`] named by `KEY=VALUE` arguments replaced: `k`,
/// `weight_width`, `normal_weight`, `regularization`, `centre_spacing`, `offset`,
/// `gap_fields`.
pub fn fit_params(mut params: FitParams, overrides: &[String]) -> Result<FitParams, String> {
    for (key, v) in key_values(overrides)? {
        match key {
            "k" => params.k = v as usize,
            "weight_width" => params.weight_width = v,
            "normal_weight" => params.normal_weight = v,
            "regularization" => params.regularization = v,
            "centre_spacing" => params.centre_spacing = v,
            "offset" => params.offset = v,
            "gap_fields" => params.gap_fields = v,
            "k_even" => params.k_even = v as usize,
            "even_lean" => params.even_lean = v,
            "misfit_width" => params.misfit_width = v,
            _ => return Err(format!("{key}: not a fit parameter this probe knows")),
        }
    }
    Ok(params)
}

/// Fit `points` with their own normals, no progress or stage reports; errors as text.
pub fn fit(points: &PointSet, params: &FitParams) -> Result<Reconstruction, String> {
    reconstruct(
        points,
        params,
        NormalPolicy::Keep,
        &mut IgnoreStages,
        &NoProgress,
    )
    .map_err(|e| e.to_string())
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
