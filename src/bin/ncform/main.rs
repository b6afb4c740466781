//! The `ncform` command line. Exit codes, one meaning each
//! (`docs/cases.md`, "Exit codes"): 0 complete, 1 bad input or set-up
//! error, 2 command-line usage, 3 solve incomplete, 4 interrupted by
//! SIGINT/SIGTERM, 5 some outputs not written.

use std::io::{self, BufReader};
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use ncform::cli::check::check_command;
use ncform::cli::export::{ExportCommandError, export_command, map_command};
use ncform::cli::fit::fit_command;
use ncform::cli::run::run_command;
use ncform::cli::sweep::{
    SweepAction, collect_command, parse_points, slurm_options, sweep_command,
};
use ncform::cli::{material_check, material_curves, material_eval};
use ncform::handoff::abaqus::AbaqusElement;
use ncform::handoff::export::{Format, HandoffOptions};
use ncform::material::MaterialSpec;
use ncform::material::params::{DEFAULT_SET, NAMED_SETS};
use ncform::report::ExitStatus;
use ncform::solver::CancelToken;
use ncform::study::RunOptions;

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
    /// the quasi-static or the explicit solver; every set-up check runs
    /// first and the estimate is printed (not with --quiet); writes CSV,
    /// PNG, VTU/PVD, a JSON summary, status.json (with the manifest) and
    /// case.resolved.json (the resolved case and its provenance). An earlier run
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
    /// Check a case file without running it (a dry run): read it, build it,
    /// pass every set-up check of its solver, and print the estimated
    /// increments or load steps, a rough run time and the size of the
    /// outputs. Writes nothing. Exit: 0 ready to run, 1 bad input.
    Check {
        /// The case file (TOML), e.g. cases/oat45.toml.
        case: PathBuf,
    },
    /// Identify a fabric's law parameters from its measured off-axis
    /// tension tests (force and MDZ strains): bounded Levenberg–Marquardt
    /// on exact sensitivities, with what the data determine (1σ,
    /// correlations, weak combinations, warnings). Writes fitted.toml,
    /// fit.json, fit.csv, fit_curves.csv and pictures (docs/fit.md). Exit:
    /// 0 converged, 1 bad input, 3 not converged (best point written), 4
    /// interrupted, 5 outputs missing.
    Fit {
        /// The fit file (TOML), e.g. cases/fit/fit.toml.
        fit: PathBuf,
        /// Output folder (default: out/<fit file name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// No progress output.
        #[arg(long)]
        quiet: bool,
    },
    /// Hand a formed part on to structural analysis: the formed plies of a
    /// forming run's folder (their mesh and per-element fibre directions;
    /// a stack's other plies mapped onto the first's mesh) as an Abaqus,
    /// LS-DYNA or CalculiX deck whose orientations the code honours
    /// (docs/export.md). Exit: 0 written, 1 bad input, 5 not written.
    Export {
        /// The run folder (written by `ncform run` on a forming case).
        run: PathBuf,
        /// The target format.
        #[arg(long, value_enum)]
        format: FormatArg,
        /// The deck to write.
        #[arg(long)]
        out: PathBuf,
        /// Abaqus elements: shell (S3R/S4R, Standard and Explicit) or
        /// membrane (M3D3; distribution orientations: Standard only).
        #[arg(long, value_enum, default_value = "shell")]
        element: ElementArg,
        #[command(flatten)]
        handoff: HandoffArgs,
    },
    /// Map the formed plies of a forming run onto your structural mesh (an
    /// Abaqus .inp of S3/S3R/S4/S4R/M3D3/M3D4 elements, its labels kept):
    /// per element the fibre direction averaged over its area (orientation
    /// tensor), written as a deck with orientations, and <out>.map.csv;
    /// elements with no ply within the tolerance get none and are counted
    /// on stderr (docs/export.md). Exit: 0 written, 1 bad input, 5 not
    /// written.
    Map {
        /// The run folder.
        run: PathBuf,
        /// The structural mesh (Abaqus .inp).
        #[arg(long)]
        onto: PathBuf,
        /// The target format.
        #[arg(long, value_enum)]
        format: FormatArg,
        /// The deck to write.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        handoff: HandoffArgs,
    },
    /// A parameter study: every point of a sweep file's design (grid,
    /// one-at-a-time, lhs, monte-carlo, sobol, morris) in a folder of its
    /// own with the exact case it runs, run here N at a time or submitted
    /// as Slurm job arrays; resumable after Ctrl-C, SIGTERM or SIGKILL
    /// (docs/studies.md). `ncform sweep SWEEP.toml --out DIR` starts;
    /// `ncform sweep DIR --resume` runs what is not complete; `ncform sweep
    /// DIR --status` tells. Exit: 0 every point complete (or submitted), 1
    /// bad input, 3 a point failed, 4 interrupted.
    Sweep {
        /// The sweep file (TOML), or with --resume, --status or --points
        /// the sweep folder.
        target: PathBuf,
        /// The sweep folder to make (a new sweep).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Run the points of the sweep folder that are not complete.
        #[arg(long)]
        resume: bool,
        /// Print what is complete, failed, running, queued, pending.
        #[arg(long, conflicts_with_all = ["resume", "out", "points"])]
        status: bool,
        /// Run these points of the sweep folder here, one after another
        /// (what a Slurm task runs): 3,4,5 or 3-7.
        #[arg(long)]
        points: Option<String>,
        /// Points run at once (default: one per core).
        #[arg(long)]
        jobs: Option<usize>,
        /// Threads of each point's run (default: the cores shared among
        /// the jobs).
        #[arg(long)]
        threads: Option<usize>,
        /// Rerun complete points whose inputs or binary changed (else a
        /// resume refuses them).
        #[arg(long)]
        rerun_changed: bool,
        /// On a resume, leave failed points failed (else they are rerun).
        #[arg(long)]
        skip_failed: bool,
        /// No progress line.
        #[arg(long)]
        quiet: bool,
        /// Only prepare the sweep folder (every point's case checked and
        /// written, the manifest); run nothing (run later with --resume).
        #[arg(long, requires = "out")]
        prepare_only: bool,
        /// Submit the points as Slurm job arrays instead of running them
        /// here.
        #[arg(long)]
        slurm: bool,
        /// Slurm partition.
        #[arg(long, requires = "slurm")]
        partition: Option<String>,
        /// Slurm time limit of a task (e.g. 01:00:00).
        #[arg(long, requires = "slurm")]
        time: Option<String>,
        /// Array tasks running at once (--array=0-N%M).
        #[arg(long, requires = "slurm")]
        max_parallel: Option<usize>,
        /// Points run one after another by each array task.
        #[arg(long, default_value_t = 1, requires = "slurm")]
        points_per_task: usize,
        /// CPUs of each task (the run's threads).
        #[arg(long, default_value_t = 1, requires = "slurm")]
        cpus_per_task: usize,
        /// Any other sbatch option, as one argument (repeat), e.g.
        /// --sbatch-arg=--mem=2G.
        #[arg(long = "sbatch-arg", requires = "slurm", allow_hyphen_values = true)]
        sbatch_args: Vec<String>,
    },
    /// Gather a sweep's results: DIR/results.csv (one row per point: the
    /// varied keys, status, the case's scalar results, wall time, the
    /// sweep file's responses, feasibility), plots of each result against
    /// each factor (and a map for a two-factor grid) in DIR/plots, and
    /// for a Sobol' or Morris design DIR/sensitivity.json
    /// (docs/studies.md). Exit: 0 written, 1 bad input.
    Collect {
        /// The sweep folder.
        dir: PathBuf,
    },
    /// The membrane law at material points: evaluation, curves, parameter sets.
    Material {
        #[command(subcommand)]
        command: MaterialCommand,
    },
}

/// `--format`.
#[derive(Clone, Copy, clap::ValueEnum)]
enum FormatArg {
    /// Abaqus input deck.
    Abaqus,
    /// LS-DYNA keyword deck.
    #[value(name = "ls-dyna")]
    LsDyna,
    /// CalculiX input deck (layered oriented solids).
    Calculix,
}

impl From<FormatArg> for Format {
    fn from(f: FormatArg) -> Self {
        match f {
            FormatArg::Abaqus => Format::Abaqus,
            FormatArg::LsDyna => Format::LsDyna,
            FormatArg::Calculix => Format::Calculix,
        }
    }
}

/// `--element`.
#[derive(Clone, Copy, clap::ValueEnum)]
enum ElementArg {
    /// S3R / S4R.
    Shell,
    /// M3D3 / M3D4.
    Membrane,
}

/// What `export` and `map` take alike: which plies and state, and how
/// far a ply may lie from an element.
#[derive(clap::Args)]
struct HandoffArgs {
    /// A ply by name or number from 1, bottom to top; repeat for a stack
    /// or several plies (default: every ply).
    #[arg(long = "ply")]
    plies: Vec<String>,
    /// The state (the NNNN of the run's vtu/<ply>_NNNN.vtu; default: the
    /// last).
    #[arg(long)]
    state: Option<usize>,
    /// Hand on the last converged state of a run that did not finish (the
    /// header says so).
    #[arg(long)]
    incomplete: bool,
    /// Largest distance from an element to a ply that gives it a
    /// direction [mm] (a stack's other plies onto the first's mesh, or
    /// every ply onto the structural mesh).
    #[arg(long, default_value_t = ncform::handoff::map::DEFAULT_TOLERANCE)]
    tolerance: f64,
}

impl HandoffArgs {
    /// The hand-off options, the tolerance checked.
    fn options(self) -> Result<HandoffOptions, String> {
        let tolerance = self.tolerance;
        if !(tolerance.is_finite() && tolerance > 0.0) {
            return Err(format!(
                "--tolerance {tolerance}: expected a distance > 0 mm"
            ));
        }
        Ok(HandoffOptions {
            plies: self.plies,
            state: self.state,
            incomplete: self.incomplete,
            map: ncform::handoff::map::MapOptions {
                tolerance,
                ..Default::default()
            },
        })
    }
}

/// The exit of `export` or `map`: the line on stdout, or the error on
/// stderr with 1 (bad input) or 5 (not written).
fn handoff_exit(result: Result<String, ExportCommandError>) -> ExitCode {
    match result {
        Ok(line) => {
            use std::io::Write as _;
            // A closed pipe is not a failure: the deck is on disk.
            let _ = writeln!(io::stdout(), "{line}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(if e.is_input() { 1 } else { 5 })
        }
    }
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
    ignore_file_size_signal();
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

/// Sizes the thread pools that a run makes for itself (the explicit
/// solver's) to the sweep's share per point, unless RAYON_NUM_THREADS is
/// set: a sweep of N jobs then does not run N pools of every core.
fn set_default_threads(threads: usize) {
    if std::env::var_os("RAYON_NUM_THREADS").is_none() {
        // SAFETY: set before any thread of this process is started (the
        // sweep's workers and pools start after this call).
        unsafe { std::env::set_var("RAYON_NUM_THREADS", threads.to_string()) };
    }
}

/// A file-size limit (`ulimit -f`) makes a write that goes past it fail
/// with EFBIG — an output not written, exit code 5 — instead of SIGXFSZ
/// killing the process with `status.json` still saying `running`.
fn ignore_file_size_signal() {
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to SIG_IGN at start-up, before
    // any other thread exists, installs no handler code.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
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

/// The command's work; its error is what `main` prints after `error: `
/// (every seam below returns a typed error; here only its message counts).
fn run(cli: Cli) -> Result<ExitCode, Box<dyn std::error::Error>> {
    match cli.command {
        Command::Run { case, out, quiet } => {
            let status =
                run_command(&case, out, quiet, &cancel_on_signals()).map_err(|e| e.to_string())?;
            Ok(exit(status))
        }
        Command::Fit { fit, out, quiet } => {
            let status =
                fit_command(&fit, out, quiet, &cancel_on_signals()).map_err(|e| e.to_string())?;
            Ok(exit(status))
        }
        Command::Export {
            run,
            format,
            out,
            element,
            handoff,
        } => {
            let options = handoff.options()?;
            let element = match element {
                ElementArg::Shell => AbaqusElement::Shell,
                ElementArg::Membrane => AbaqusElement::Membrane,
            };
            Ok(handoff_exit(export_command(
                &run,
                format.into(),
                element,
                &options,
                &out,
            )))
        }
        Command::Map {
            run,
            onto,
            format,
            out,
            handoff,
        } => {
            let options = handoff.options()?;
            Ok(handoff_exit(
                map_command(&run, &onto, format.into(), &options, &out).map(|(line, warnings)| {
                    for w in warnings {
                        eprintln!("warning: {w}");
                    }
                    line
                }),
            ))
        }
        Command::Sweep {
            target,
            out,
            resume,
            status,
            points,
            jobs,
            threads,
            rerun_changed,
            skip_failed,
            quiet,
            prepare_only,
            slurm,
            partition,
            time,
            max_parallel,
            points_per_task,
            cpus_per_task,
            sbatch_args,
        } => {
            let action = match (status, resume, points, out) {
                (true, ..) => SweepAction::Status(target),
                (false, _, Some(list), None) => SweepAction::Points(target, parse_points(&list)?),
                (false, true, None, None) => SweepAction::Resume(target),
                (false, false, None, Some(out)) => SweepAction::Start { sweep: target, out },
                (false, false, None, None) => {
                    return Err("ncform sweep: give --out DIR for a sweep file, or --resume / --status / --points for a sweep folder".into());
                }
                _ => {
                    return Err("ncform sweep: --out starts a new sweep from a sweep file; --resume and --points take the sweep folder instead".into());
                }
            };
            let options = RunOptions {
                jobs,
                threads,
                rerun_changed,
                skip_failed,
                quiet,
                prepare_only,
                slurm: slurm.then(|| {
                    slurm_options(
                        partition,
                        time,
                        max_parallel,
                        points_per_task,
                        cpus_per_task,
                        sbatch_args,
                    )
                }),
            };
            if let (Some(0), _) | (_, Some(0)) = (options.jobs, options.threads) {
                return Err("ncform sweep: --jobs and --threads must be at least 1".into());
            }
            let (_, per_point) = ncform::study::jobs_and_threads(&options);
            set_default_threads(per_point);
            let status = sweep_command(&action, &options, &cancel_on_signals())?;
            Ok(exit(status))
        }
        Command::Collect { dir } => Ok(exit(collect_command(&dir)?)),
        Command::Check { case } => {
            let status = check_command(&case).map_err(|e| e.to_string())?;
            Ok(exit(status))
        }
        Command::Material { command } => match command {
            MaterialCommand::Eval { params } => {
                let spec = MaterialSpec::load(&params)?;
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
                let spec = MaterialSpec::load(&params)?;
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
                let spec = MaterialSpec::load(&params)?;
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
