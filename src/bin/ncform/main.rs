//! The `ncform` command line. Exit codes, one meaning each
//! (`docs/cases.md`, "Exit codes"): 0 complete, 1 bad input or set-up
//! error, 2 command-line usage, 3 solve incomplete, 4 interrupted by
//! SIGINT/SIGTERM, 5 some outputs not written.

use std::io::{self, BufReader};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use ncform::case::OatCase;
use ncform::case::forming::{FormingCase, is_forming};
use ncform::cli::form::run_forming_with;
use ncform::cli::run::{Progress, default_out_dir, run_case_with};
use ncform::cli::run_folder::ExitStatus;
use ncform::cli::{material_check, material_curves, material_eval};
use ncform::material::MaterialSpec;
use ncform::material::params::{DEFAULT_SET, NAMED_SETS};
use ncform::solver::{CancelToken, RunStatus};

/// Forming simulation of dry UD non-crimp fabrics (Schäfer et al. 2024 law).
/// Units: mm, N, MPa, tonne/mm³, s.
#[derive(Parser)]
#[command(name = "ncform", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a case file (an off-axis tension test or a forming set-up) with
    /// the quasi-static or the explicit solver; writes CSV, PNG, VTU/PVD,
    /// a JSON summary and status.json (with the manifest). An earlier run
    /// in the output folder is moved aside to <out>.previous; SIGINT or
    /// SIGTERM stops at the next safe point and writes what was reached.
    /// Exit: 0 complete, 1 bad input, 2 usage, 3 incomplete, 4
    /// interrupted, 5 outputs missing.
    Run {
        /// The case file (TOML), e.g. cases/oat45.toml.
        case: PathBuf,
        /// Output folder (default: out/<case name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// No progress output.
        #[arg(long)]
        quiet: bool,
    },
    /// The membrane law at material points: evaluation, curves, parameter sets.
    Material {
        #[command(subcommand)]
        command: MaterialCommand,
    },
}

#[derive(Subcommand)]
enum MaterialCommand {
    /// Read JSON lines {"C": [[c11,c12],[c12,c22]], "fiber_angle_deg": θ} on
    /// stdin; write W, S, the tangent and the invariants as JSON lines.
    Eval {
        /// A named parameter set or a TOML file.
        #[arg(long, default_value = DEFAULT_SET, value_name = "NAME|FILE")]
        params: String,
    },
    /// Write the stress functions, the coupling k11 and the energy
    /// contributions as CSV and PNG.
    Curves {
        /// A named parameter set or a TOML file.
        #[arg(long, default_value = DEFAULT_SET, value_name = "NAME|FILE")]
        params: String,
        /// Output folder (created if missing).
        #[arg(long, default_value = "out/material-curves")]
        out: PathBuf,
    },
    /// Check the stress and the tangent against finite differences of the
    /// energy and the stress at random states over every branch.
    Check {
        /// A named parameter set or a TOML file.
        #[arg(long, default_value = DEFAULT_SET, value_name = "NAME|FILE")]
        params: String,
        /// Number of random states.
        #[arg(long, default_value_t = 10_000)]
        states: usize,
        /// Seed of the state sampler.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Print a named parameter set as TOML, to start a file of your own;
    /// without a name, list the named sets.
    Params {
        /// The set's name.
        name: Option<String>,
    },
}

/// A line on stdout. A closed pipe (`ncform run … | head -1`) is not a
/// failure of the command: the results are on disk, so the error is
/// dropped instead of panicking as `println!` does.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

/// Text on stdout without a newline, as [`say!`].
macro_rules! say_raw {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stdout(), $($arg)*);
    }};
}

fn main() -> ExitCode {
    // clap exits with 2 on a usage error (and 0 for --help, --version).
    let cli = Cli::parse();
    match run(cli) {
        Ok(code) => code,
        Err(message) => {
            eprintln!("error: {message}");
            exit(ExitStatus::BadInput)
        }
    }
}

fn exit(status: ExitStatus) -> ExitCode {
    ExitCode::from(status.code())
}

/// A token cancelled by the first SIGINT or SIGTERM (the solvers then stop
/// at their next safe point and the results so far are written); a second
/// signal ends the process at once with the interrupted code, leaving
/// `status.json` as `running`.
fn cancel_on_signals() -> CancelToken {
    let token = CancelToken::new();
    let handler = token;
    let installed = ctrlc::set_handler(move || {
        if handler.is_cancelled() {
            eprintln!("ncform: second interrupt: stopping at once; outputs may be missing");
            std::process::exit(i32::from(ExitStatus::Interrupted.code()));
        }
        eprintln!(
            "ncform: interrupt: stopping at the next safe point and writing the results so far (interrupt again to stop at once)"
        );
        handler.cancel();
    });
    if let Err(e) = installed {
        eprintln!(
            "warning: cannot catch SIGINT/SIGTERM ({e}); an interrupt ends the run without marking it"
        );
    }
    token
}

/// The exit of a run: its status, and on stderr what is not as asked,
/// with the load reached and the load attempted written by `reached` and
/// `attempted`.
fn run_exit(
    status: &RunStatus,
    exit_status: ExitStatus,
    reached: impl Fn(f64) -> String,
    attempted: impl Fn(f64) -> String,
) -> ExitCode {
    match status {
        RunStatus::Complete => {}
        RunStatus::Incomplete {
            load_reached,
            load_attempted,
            reason,
        } => eprintln!(
            "error: the solve failed in the step from {} to {}: {reason}; results up to {} are written and marked incomplete",
            reached(*load_reached),
            attempted(*load_attempted),
            reached(*load_reached)
        ),
        RunStatus::Interrupted { load_reached } => eprintln!(
            "interrupted: results up to {} are written and marked interrupted",
            reached(*load_reached)
        ),
    }
    if exit_status == ExitStatus::OutputsMissing {
        eprintln!("error: some outputs could not be written (listed above and in status.json)");
    }
    exit(exit_status)
}

/// `ncform run` for a forming case.
fn run_forming_case(
    case: &std::path::Path,
    out: Option<PathBuf>,
    quiet: bool,
) -> Result<ExitCode, String> {
    let spec = FormingCase::load(case).map_err(|e| e.to_string())?;
    let out = out.unwrap_or_else(|| default_out_dir(case));
    let progress = if quiet {
        Progress::Quiet
    } else {
        Progress::auto_programme()
    };
    let summary = run_forming_with(&spec, &out, progress, &cancel_on_signals())?;
    let work = match &summary.explicit {
        None => format!(
            "{} steps, {} Newton iterations, {} augmentations",
            summary.steps, summary.newton_iterations, summary.augmentations
        ),
        Some(e) => format!(
            "explicit: {} increments, max KE/IE {:.2} %, energy balance {:.1e}",
            e.increments,
            100.0 * e.max_kinetic_ratio,
            e.max_relative_balance_error
        ),
    };
    let forces: Vec<String> = summary
        .history
        .last()
        .map(|row| {
            summary
                .tools
                .iter()
                .zip(&row.tools)
                .map(|(name, t)| format!("{name}: {:.4} N at {:.3} mm", t.force, t.displacement))
                .collect()
        })
        .unwrap_or_default();
    report(&spec.title, &work, summary.wall_seconds, &forces, &out);
    Ok(run_exit(
        &summary.status,
        summary.exit_status,
        |load| format!("programme fraction {load}"),
        |load| load.to_string(),
    ))
}

/// The run's one-line summary (title, work, wall time, the last forces)
/// and where its results are.
fn report(title: &str, work: &str, wall_seconds: f64, forces: &[String], out: &Path) {
    let forces = if forces.is_empty() {
        String::new()
    } else {
        format!("; {}", forces.join(", "))
    };
    say!("{title}: {work}, {wall_seconds:.2} s{forces}");
    say!("results in {}", out.display());
}

fn run(cli: Cli) -> Result<ExitCode, String> {
    match cli.command {
        Command::Run { case, out, quiet } => {
            let text = std::fs::read_to_string(&case)
                .map_err(|e| format!("case file '{}': {e}", case.display()))?;
            if is_forming(&text) {
                return run_forming_case(&case, out, quiet);
            }
            let spec = OatCase::load(&case).map_err(|e| e.to_string())?;
            let out = out.unwrap_or_else(|| default_out_dir(&case));
            let progress = if quiet {
                Progress::Quiet
            } else {
                Progress::auto(spec.displacement)
            };
            let summary = run_case_with(&spec, &out, progress, &cancel_on_signals())?;
            let forces: Vec<String> = summary
                .forces
                .iter()
                .map(|(d, f)| format!("{f:.3} N at {d} mm"))
                .collect();
            let work = match &summary.explicit {
                None => format!(
                    "{} steps, {} Newton iterations",
                    summary.steps, summary.newton_iterations
                ),
                Some(e) => format!(
                    "explicit: {} increments, {:.1} M element-cycles/s on {} threads, max KE/IE {:.2} %, energy balance {:.1e}",
                    e.increments,
                    e.element_cycles_per_second / 1e6,
                    e.threads,
                    100.0 * e.max_kinetic_ratio,
                    e.max_relative_balance_error
                ),
            };
            report(&spec.title, &work, summary.wall_seconds, &forces, &out);
            Ok(run_exit(
                &summary.status,
                summary.exit_status,
                |d| format!("d = {d} mm"),
                |d| format!("{d} mm"),
            ))
        }
        Command::Material { command } => match command {
            MaterialCommand::Eval { params } => {
                let spec = MaterialSpec::load(&params).map_err(|e| e.to_string())?;
                let stdin = io::stdin();
                let summary = material_eval::run(
                    &spec.material,
                    BufReader::new(stdin.lock()),
                    io::BufWriter::new(io::stdout().lock()),
                    io::stderr().lock(),
                    "stdin",
                )
                .map_err(|e| format!("I/O error: {e}"))?;
                if summary.failed > 0 {
                    eprintln!(
                        "material eval: {} line(s) answered, {} line(s) with errors",
                        summary.answered, summary.failed
                    );
                    return Ok(exit(ExitStatus::BadInput));
                }
                Ok(ExitCode::SUCCESS)
            }
            MaterialCommand::Curves { params, out } => {
                let spec = MaterialSpec::load(&params).map_err(|e| e.to_string())?;
                // Bad input (exit 1) apart from a write failure (exit 5).
                let law = material_curves::curves_law(&spec)?;
                let written = match material_curves::write_law_curves(&spec, &law, &out) {
                    Ok(written) => written,
                    Err(message) => {
                        eprintln!("error: {message}");
                        return Ok(exit(ExitStatus::OutputsMissing));
                    }
                };
                for path in written {
                    say!("{}", path.display());
                }
                Ok(ExitCode::SUCCESS)
            }
            MaterialCommand::Check {
                params,
                states,
                seed,
            } => {
                let spec = MaterialSpec::load(&params).map_err(|e| e.to_string())?;
                let report = material_check::run_check(&spec, states, seed);
                say_raw!("{}", material_check::format_report(&spec, &report));
                if report.failed > 0 || report.rejected > 0 {
                    return Ok(exit(ExitStatus::BadInput));
                }
                Ok(ExitCode::SUCCESS)
            }
            MaterialCommand::Params { name } => match name {
                None => {
                    for (name, _) in NAMED_SETS {
                        let spec = MaterialSpec::named(name).expect("named set");
                        let default = if *name == DEFAULT_SET {
                            " (default)"
                        } else {
                            ""
                        };
                        say!("{name}{default}: {}", spec.description);
                    }
                    Ok(ExitCode::SUCCESS)
                }
                Some(name) => {
                    let text = MaterialSpec::named_text(&name).ok_or_else(|| {
                        format!(
                            "no named parameter set '{name}'; the sets are: {}",
                            NAMED_SETS
                                .iter()
                                .map(|(n, _)| *n)
                                .collect::<Vec<_>>()
                                .join(", ")
                        )
                    })?;
                    say_raw!("{text}");
                    Ok(ExitCode::SUCCESS)
                }
            },
        },
    }
}
