//! `radbench export RUN_OR_CAPTURE --npz|--hdf5`: a capture's or a whole run's arrays in one
//! file a notebook loads in a line (docs/export.md): the decimated I/Q in volts, the complex
//! range profile and its range axis, the detections, the transmitted reference and bits, the
//! options. The arrays are what `radbench process` computes from the same files.

use radbench::campaign::Manifest;
use radbench::campaign::{export_run, put_all};
use radbench::exit::bad_input;
use radbench::measure;
use radbench::measure::export_capture;

use radbench::storage::{ComplexDtype, ExportFormat, ExportWriter};
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("format").required(true).args(["npz", "hdf5"])))]
pub struct Args {
    /// A capture folder (with capture.sigmf-meta), a capture's .sigmf-meta file, or a
    /// campaign's run folder (with manifest.toml: every measured step).
    #[arg(value_name = "RUN_OR_CAPTURE")]
    pub input: PathBuf,
    /// Write a NumPy .npz (numpy.load(FILE, allow_pickle=False)).
    #[arg(long)]
    pub npz: bool,
    /// Write an HDF5 file (h5py.File(FILE)).
    #[arg(long)]
    pub hdf5: bool,
    /// The file to write (default: beside the input, named after it: RUN_DIR.npz, RUN_DIR.h5).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Replace the output file if it exists.
    #[arg(long)]
    pub force: bool,
    /// How complex arrays (I/Q, profiles, references) are stored: complex128 (float64 parts,
    /// every digit) or complex64 (float32 parts: half the bytes, about 7 significant digits).
    #[arg(long, value_enum, default_value_t = Dtype::Complex128, value_name = "DTYPE")]
    pub dtype: Dtype,
}

/// `--dtype`: the NumPy names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Dtype {
    Complex64,
    Complex128,
}

impl From<Dtype> for ComplexDtype {
    fn from(d: Dtype) -> Self {
        match d {
            Dtype::Complex64 => ComplexDtype::Complex64,
            Dtype::Complex128 => ComplexDtype::Complex128,
        }
    }
}

/// What the input is.
enum Input {
    Capture(measure::Source),
    Run,
}

fn classify(input: &Path) -> anyhow::Result<Input> {
    let what = "give a capture folder (with capture.sigmf-meta), a capture's .sigmf-meta file or \
                a campaign's run folder (with manifest.toml)";
    let meta = std::fs::symlink_metadata(input);
    if meta.is_err() {
        return Err(bad_input(format!(
            "{}: no such file or folder; {what}",
            input.display()
        )));
    }
    let name = input.to_string_lossy().to_lowercase();
    let capture = |path: &Path| {
        measure::sigmf(path)
            .map(Input::Capture)
            .map_err(|e| bad_input(format!("{}: {}", e.path.display(), e.reason)))
    };
    if input.is_dir() {
        if input.join("capture.sigmf-meta").is_file() {
            return capture(&input.join("capture.sigmf-meta"));
        }
        if input.join(radbench::campaign::MANIFEST_FILE).is_file() {
            if Manifest::load(input).is_ok() {
                return Ok(Input::Run);
            }
            if input.join("summary.json").is_file() {
                return Err(bad_input(format!(
                    "{}: a re-processing `radbench process` wrote, which holds no capture; \
                     export the capture it processed (its manifest.toml names it under sources)",
                    input.display()
                )));
            }
            // A run folder whose manifest is unreadable: say why.
            Manifest::load(input)?;
        }
        return Err(bad_input(format!(
            "{}: neither a capture nor a run folder; {what}",
            input.display()
        )));
    }
    if name.ends_with(".sigmf-meta") || name.ends_with(".sigmf-data") {
        return capture(input);
    }
    if name.ends_with(".trc") {
        return Err(bad_input(format!(
            "{}: export reads radbench's captures: give the capture folder the .trc file is in",
            input.display()
        )));
    }
    Err(bad_input(format!(
        "{}: neither a capture nor a run folder; {what}",
        input.display()
    )))
}

/// The default output: beside the input, named after it (a folder `x` gives `x.npz`; a file
/// `dir/capture.sigmf-meta`, `dir/capture.npz`).
fn default_out(input: &Path, format: ExportFormat) -> anyhow::Result<PathBuf> {
    let full = std::fs::canonicalize(input)?;
    let ext = format.extension();
    if full.is_dir() {
        let name = full
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "export".into());
        let parent = input
            .parent()
            .filter(|p| !p.as_os_str().is_empty() && input.file_name().is_some())
            .map(Path::to_path_buf)
            .or_else(|| full.parent().map(Path::to_path_buf))
            .unwrap_or_default();
        Ok(parent.join(format!("{name}.{ext}")))
    } else {
        let name = input
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let stem = name
            .strip_suffix(".sigmf-meta")
            .or_else(|| name.strip_suffix(".sigmf-data"))
            .unwrap_or(&name);
        Ok(input.with_file_name(format!("{stem}.{ext}")))
    }
}

pub(crate) fn run(args: Args, _global: &super::global::Global) -> anyhow::Result<()> {
    let format = if args.hdf5 {
        ExportFormat::Hdf5
    } else {
        ExportFormat::Npz
    };
    let input = classify(&args.input)?;
    let out = match &args.out {
        Some(o) => o.clone(),
        None => default_out(&args.input, format)?,
    };
    if let Ok(m) = std::fs::symlink_metadata(&out) {
        if m.is_dir() {
            return Err(bad_input(format!(
                "--out {}: is a folder; give the file to write",
                out.display()
            )));
        }
        if !args.force {
            return Err(bad_input(format!(
                "{}: exists already; pass --force to replace it, or --out another file",
                out.display()
            )));
        }
    }
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|source| radbench::storage::StorageError::Io {
            path: parent.to_path_buf(),
            source,
        })?;
    }
    let mut writer = ExportWriter::create(&out, format)?.with_complex_dtype(args.dtype.into());
    let started = std::time::Instant::now();
    let text = match input {
        Input::Capture(source) => {
            let exported = export_capture(&source, &[])?;
            for entries in exported.processings {
                put_all(&mut writer, "", entries)?;
            }
            format!("the capture {}", source.files()[0].display())
        }
        Input::Run => {
            let tty = std::io::IsTerminal::is_terminal(&std::io::stderr());
            let mut progress = |group: &str, k: usize, n: usize| {
                if tty {
                    eprintln!("{group} exported ({k} of {n})");
                }
            };
            let done = export_run(&args.input, &mut writer, &mut progress)?;
            if done.steps.is_empty() {
                return Err(bad_input(format!(
                    "{}: no step of the run is measured yet: nothing to export",
                    args.input.display()
                )));
            }
            if !done.pending.is_empty() {
                eprintln!(
                    "note: steps {} are not measured yet (the run is not complete) and are not \
                     in the file",
                    done.pending
                        .iter()
                        .map(ToString::to_string)
                        .collect::<Vec<_>>()
                        .join(", ")
                );
            }
            format!(
                "{} steps of the run {} (a group each: {} .. {})",
                done.steps.len(),
                args.input.display(),
                done.steps[0],
                done.steps[done.steps.len() - 1]
            )
        }
    };
    let path = writer.finish()?;
    super::terminal::out(&format!(
        "exported {text} to {} in {:.1} s",
        path.display(),
        started.elapsed().as_secs_f64()
    ))
}
