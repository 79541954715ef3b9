//! The `proprioscope` command line: headless commands over the same core
//! the desktop app uses.

/// Writes a line to standard output, returning the error instead of
/// panicking: a closed pipe (`proprioscope robot-info … | head -1`) ends
/// the program quietly in `main`.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($arg)*)?;
    }};
}

mod cli;

use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result, bail};
use clap::{Parser, Subcommand};
use glam::DVec3;

use proprioscope::core::config::limits;
use proprioscope::core::robot::kinematics::RobotPose;
use proprioscope::core::robot::model::Robot;
use proprioscope::core::robot::torque::joint_torques;
use proprioscope::core::surface::sampling::{Surface, SurfaceRequest};
use proprioscope::io::builtin::{LWR4PLUS_GLB_PATH, load_robot, lwr4plus_glb_generated};
use proprioscope::io::scene::Scene;
use proprioscope::io::urdf::{MeshSelection, UrdfOptions};

#[derive(Parser)]
#[command(
    name = "proprioscope",
    version,
    about = "Where is a robot arm touched, and how hard, from its joint torques alone"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
// Parsed once at start: boxing the larger options would gain nothing.
#[allow(clippy::large_enum_variant)]
enum Command {
    /// Joint torques of a push: from a scene file, or from --robot, --q,
    /// --link, --point and --force (world frame, SI).
    Torques(TorquesArgs),
    /// Opens the desktop app on a scene file, a URDF, a built-in robot or
    /// a recorded session (JSON or CSV), replayed on a timeline.
    View {
        /// A scene (`.json`), a URDF, `lwr4plus` / `simple6`, a session or
        /// a robot recording (`.mcap`, `.bag`); with --live, the robot.
        #[arg(required_unless_present = "live")]
        target: Option<String>,
        /// Listen for a live session on this address (`host:port` or
        /// `tcp://host:port`, `udp://host:port`): frames as JSON lines
        /// fill the timeline, each filtered with the frames before it as it
        /// arrives, and the view follows the newest (see `stream`).
        #[arg(long)]
        live: Option<String>,
        /// Also publish what the view shows to Foxglove over its WebSocket
        /// protocol on this address (default 127.0.0.1:8765, loopback);
        /// open it in Foxglove with Open connection → Foxglove WebSocket →
        /// `ws://ADDR`.
        #[arg(long, num_args = 0..=1, default_missing_value = proprioscope::io::foxglove::serve::DEFAULT_SERVE_ADDR)]
        serve: Option<String>,
        /// The robot of a session (overrides the session's; a CSV session
        /// needs one): a built-in name or a URDF.
        #[arg(long)]
        robot: Option<String>,
        /// Extra folder for `package://` URIs (repeatable).
        #[arg(long = "package-path")]
        package_paths: Vec<PathBuf>,
    },
    /// Renders the full app for a scene headless (no window or display
    /// needed) and writes a PNG.
    Screenshot {
        /// A scene (`.json`), a URDF, a built-in robot name or a session;
        /// none: the default scene.
        target: Option<String>,
        /// The robot of a session (see `view`).
        #[arg(long)]
        robot: Option<String>,
        /// The session frame to show (0-based, among its good frames).
        #[arg(long)]
        frame: Option<usize>,
        /// Contacts looked for at once, 1 or 2 (as the panel's *contacts*;
        /// default: the scene's, else 1).
        #[arg(long, value_parser = clap::value_parser!(u8).range(1..=2))]
        contacts: Option<u8>,
        /// The PNG to write.
        #[arg(long)]
        out: PathBuf,
        /// Width, pixels (valid: 16 to 16384).
        #[arg(long, default_value_t = 1400, value_parser = clap::value_parser!(u32).range(16..=16_384))]
        width: u32,
        /// Height, pixels (valid: 16 to 16384).
        #[arg(long, default_value_t = 900, value_parser = clap::value_parser!(u32).range(16..=16_384))]
        height: u32,
    },
    /// Draws what an MCAP written by `estimate --out` holds for Foxglove at
    /// a time (the arm posed by its transforms, the heatmap, the arrows),
    /// from the file's messages alone, with the program's renderer.
    PreviewMcap {
        /// The MCAP.
        mcap: PathBuf,
        /// The time to show, s after the file's first message.
        #[arg(long, default_value_t = 0.0)]
        at: f64,
        /// The PNG to write.
        #[arg(long)]
        out: PathBuf,
        /// Width, pixels (valid: 16 to 16384).
        #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u32).range(16..=16_384))]
        width: u32,
        /// Height, pixels (valid: 16 to 16384).
        #[arg(long, default_value_t = 800, value_parser = clap::value_parser!(u32).range(16..=16_384))]
        height: u32,
    },
    /// Estimates the contact in every frame of a recorded session.
    Estimate(cli::estimate::EstimateArgs),
    /// Learns what a robot's torques carry besides contacts (observer lag,
    /// inertial error, joint friction, offsets) from a recording's free
    /// motion, and saves it for `estimate --calibration`.
    Calibrate(cli::calibrate::CalibrateArgs),
    /// Speed against accuracy of estimator configurations (table and PNG plot).
    Bench(cli::bench::BenchArgs),
    /// Writes a session drawn from the model itself (the built-in LWR
    /// pressed, with truth): presses that hold or slide, come and go,
    /// with friction, bias and noise as asked.
    Synth(cli::synth::SynthArgs),
    /// Lists a robot recording's topics (MCAP, ROS 1 bag): types, counts,
    /// rates, where times come from, float arrays; and the topics
    /// `estimate` would make frames of.
    Topics(cli::topics::TopicsArgs),
    /// Sends a recorded session to a TCP address as a live source, a JSON
    /// line a frame at the pace of its times (see `estimate --live`).
    Stream(cli::live::StreamArgs),
    /// Links and joints of a robot (built-in name or URDF path).
    RobotInfo {
        /// `simple6`, `lwr4plus` or a URDF file.
        robot: String,
        /// Extra folder for `package://` URIs (repeatable).
        #[arg(long = "package-path")]
        package_paths: Vec<PathBuf>,
    },
    /// Samples a scene's candidate links and reports, per link, the
    /// candidates drawn, buried and kept, and the exposed area.
    Surface {
        /// A scene file (JSON).
        scene: PathBuf,
        /// Override the scene's surface resolution (valid: 1 to 1000000).
        #[arg(long, value_parser = cli::counted(&limits::SURFACE_POINTS))]
        points: Option<usize>,
    },
    /// Records a scripted interactive session (the built-in LWR waving,
    /// pushed on its forearm) as the app's recorder does, until killed or
    /// for `--seconds`: the crash-safety test's subject.
    #[command(hide = true)]
    RecordDemo {
        /// The session file to write.
        #[arg(long)]
        out: PathBuf,
        /// Frames per second (valid: (0, 10000] Hz).
        #[arg(long, default_value_t = 50.0, value_parser = cli::within(&limits::RATE_HZ))]
        rate: f64,
        /// Stop after this long (default: run until killed; valid: (0, 3600] s).
        #[arg(long, value_parser = cli::within(&limits::SECONDS))]
        seconds: Option<f64>,
    },
    /// Regenerates the shipped assets: `assets/lwr4plus.glb` from the
    /// built-in robot's primitives, and the Foxglove layout
    /// `assets/foxglove-layout.json`.
    ExportAssets {
        /// Repository root to write under.
        #[arg(long, default_value = ".")]
        root: PathBuf,
    },
}

#[derive(clap::Args)]
struct TorquesArgs {
    /// A scene file (JSON); or use --robot and the options below.
    scene: Option<PathBuf>,
    /// `simple6`, `lwr4plus` or a URDF file.
    #[arg(long, conflicts_with = "scene")]
    robot: Option<String>,
    /// Sensed joint positions, rad (or m), comma separated (default all
    /// 0; valid: [-10000, 10000] each).
    #[arg(long, allow_hyphen_values = true, value_delimiter = ',', value_parser = cli::within(&limits::JOINT_POSITION))]
    q: Vec<f64>,
    /// The link pushed.
    #[arg(long)]
    link: Option<String>,
    /// Contact point x,y,z in the world frame, m (valid: [-1000, 1000] each).
    #[arg(long, allow_hyphen_values = true, value_parser = cli::vec3_within(&limits::COORDINATE))]
    point: Option<DVec3>,
    /// Force fx,fy,fz applied to the robot, world frame, N (valid:
    /// [-1e6, 1e6] each).
    #[arg(long, allow_hyphen_values = true, value_parser = cli::vec3_within(&limits::FORCE_COMPONENT))]
    force: Option<DVec3>,
    /// Extra folder for `package://` URIs (repeatable).
    #[arg(long = "package-path")]
    package_paths: Vec<PathBuf>,
    /// Print N·cm instead of N·m.
    #[arg(long)]
    ncm: bool,
    /// Print `{"joints": [{"name": ..., "torque": <N·m>}, ...]}`.
    #[arg(long)]
    json: bool,
}

/// The logger for our messages and the libraries' (wgpu, eframe and mcap
/// report through `log`): by default our progress and every warning;
/// `RUST_LOG` (e.g. `RUST_LOG=wgpu_hal=info`, `RUST_LOG=error`) replaces
/// that choice. Our progress reads as plain lines, warnings and errors
/// say so, and a library's messages name the library.
fn init_logging() {
    use std::io::Write as _;
    let mut builder = env_logger::Builder::new();
    match std::env::var("RUST_LOG") {
        Ok(spec) if !spec.trim().is_empty() => {
            builder.parse_filters(&spec);
        }
        _ => {
            builder
                .filter_level(log::LevelFilter::Warn)
                .filter_module("proprioscope", log::LevelFilter::Info);
        }
    }
    builder.format(|out, record| {
        let ours = record.target().starts_with("proprioscope");
        match (record.level(), ours) {
            (log::Level::Info, true) => writeln!(out, "{}", record.args()),
            (log::Level::Warn, true) => writeln!(out, "warning: {}", record.args()),
            (log::Level::Error, true) => writeln!(out, "error: {}", record.args()),
            (level, _) => writeln!(
                out,
                "{} [{}]: {}",
                level.as_str().to_lowercase(),
                record.target(),
                record.args()
            ),
        }
    });
    // A second logger (none here) would be the only reason this fails.
    let _ = builder.try_init();
}

fn main() -> std::process::ExitCode {
    init_logging();
    match run(Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        // The reader of our output went away (`| head`): nothing to report.
        Err(e)
            if e.chain().any(|c| {
                c.downcast_ref::<std::io::Error>()
                    .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
            }) =>
        {
            std::process::ExitCode::SUCCESS
        }
        Err(e) => {
            use std::io::Write as _;
            // The message and its causes, not `{e:?}`: with RUST_BACKTRACE
            // set (as many Rust users keep it) that adds a stack trace of
            // our own code under every bad file name or field.
            let mut text = format!("Error: {e}");
            let causes: Vec<String> = e.chain().skip(1).map(ToString::to_string).collect();
            if !causes.is_empty() {
                text.push_str("\n\nCaused by:");
                for cause in causes {
                    text.push_str("\n    ");
                    text.push_str(&cause);
                }
            }
            let _ = writeln!(std::io::stderr(), "{text}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Some(Command::Torques(args)) => torques(&args),
        Some(Command::Estimate(args)) => match &args.live {
            Some(address) => cli::live::run(&args, address),
            None => cli::estimate::run(&args),
        },
        Some(Command::Calibrate(args)) => cli::calibrate::run(&args),
        Some(Command::Bench(args)) => cli::bench::run(&args),
        Some(Command::Synth(args)) => cli::synth::run(&args),
        Some(Command::Stream(args)) => cli::live::stream(&args),
        Some(Command::Topics(args)) => cli::topics::run(&args),
        Some(Command::RobotInfo { robot, package_paths }) => robot_info(&robot, package_paths),
        Some(Command::Surface { scene, points }) => surface(&scene, points),
        Some(Command::ExportAssets { root }) => export_assets(&root),
        Some(Command::View {
            target,
            live,
            serve,
            robot,
            package_paths,
        }) => run_app(
            target.as_deref().or(robot.as_deref()),
            robot.as_deref(),
            &package_paths,
            (live, serve),
        ),
        Some(Command::Screenshot {
            target,
            robot,
            frame,
            contacts,
            out,
            width,
            height,
        }) => screenshot(
            target.as_deref(),
            robot.as_deref(),
            (frame, contacts),
            &out,
            [width, height],
        ),
        Some(Command::RecordDemo { out, rate, seconds }) => record_demo(&out, rate, seconds),
        Some(Command::PreviewMcap {
            mcap,
            at,
            out,
            width,
            height,
        }) => preview_mcap(&mcap, at, &out, [width, height]),
        None => run_app(None, None, &[], (None, None)),
    }
}

/// The push to report: robot, pose, link, point and force in the world.
struct PushCase {
    robot: Robot,
    pose: RobotPose,
    link: usize,
    point_world: DVec3,
    force_world: DVec3,
    measured: Option<Vec<f64>>,
}

fn torques(args: &TorquesArgs) -> Result<()> {
    let case = push_case(args)?;
    let tau = joint_torques(&case.robot, &case.pose, case.link, case.point_world, case.force_world);
    if let Some((name, t)) = case.robot.sensed_names().iter().zip(&tau).find(|(_, t)| !t.is_finite()) {
        bail!("the torque of {name} is {t}: the push is too large to compute (check its units)");
    }
    if args.json {
        let joints: Vec<serde_json::Value> = case
            .robot
            .sensed_names()
            .iter()
            .zip(&tau)
            .map(|(n, t)| serde_json::json!({ "name": n, "torque": t }))
            .collect();
        outln!("{}", serde_json::json!({ "joints": joints }));
    } else {
        print_torques(&case, &tau, args.ncm)?;
    }
    Ok(())
}

/// The push a `torques` command asks about, from a scene or the arguments.
fn push_case(args: &TorquesArgs) -> Result<PushCase> {
    Ok(if let Some(path) = &args.scene {
        let loaded = Scene::read(path)?.load(path)?;
        let Some(push) = loaded.push else {
            bail!(
                "{}: the scene has no push, so there are no torques to print",
                path.display()
            );
        };
        let measured = (loaded.scene.noise.sigma_newton_metres > 0.0).then(|| loaded.measured_torques());
        PushCase {
            robot: loaded.robot,
            pose: loaded.pose,
            link: push.link,
            point_world: push.point_world,
            force_world: push.force_world,
            measured,
        }
    } else {
        let Some(spec) = &args.robot else {
            bail!("give a scene file, or --robot with --link, --point and --force");
        };
        let (Some(link), Some(point_world), Some(force_world)) = (&args.link, args.point, args.force) else {
            bail!("--robot needs --link, --point x,y,z and --force fx,fy,fz");
        };
        let options = UrdfOptions {
            package_paths: args.package_paths.clone(),
            meshes: MeshSelection::None,
        };
        let robot = load_robot(spec, Path::new("."), &options)?;
        let q = if args.q.is_empty() {
            vec![0.0; robot.sensed().len()]
        } else {
            args.q.clone()
        };
        let positions = robot.joint_positions(&q, &[]).context("--q")?;
        let pose = RobotPose::new(&robot, &positions);
        let link = robot.link_id(link).context("--link")?;
        PushCase {
            robot,
            pose,
            link,
            point_world,
            force_world,
            measured: None,
        }
    })
}

/// The torque table, then which joints sense nothing and which read zero.
fn print_torques(case: &PushCase, tau: &[f64], ncm: bool) -> Result<()> {
    let names = case.robot.sensed_names();
    let (unit, scale) = if ncm { ("N·cm", 100.0) } else { ("N·m", 1.0) };
    let link_name = &case.robot.links[case.link].name;
    let (p, f) = (case.point_world, case.force_world);
    outln!(
        "robot {} · link {link_name} · point ({:.4}, {:.4}, {:.4}) m · force ({:.3}, {:.3}, {:.3}) N, world frame",
        case.robot.name,
        p.x,
        p.y,
        p.z,
        f.x,
        f.y,
        f.z
    );
    let width = names.iter().map(|n| n.len()).max().unwrap_or(5).max(5);
    if case.measured.is_some() {
        outln!(
            "{:width$}  {:>12}  {:>12}",
            "joint",
            format!("torque [{unit}]"),
            "measured"
        );
    } else {
        outln!("{:width$}  {:>12}", "joint", format!("torque [{unit}]"));
    }
    for (i, (name, t)) in names.iter().zip(tau).enumerate() {
        if let Some(m) = case.measured.as_ref().and_then(|m| m.get(i)) {
            outln!("{name:width$}  {:>12}  {:>12}", shown(t * scale), shown(m * scale));
        } else {
            outln!("{name:width$}  {:>12}", shown(t * scale));
        }
    }
    let path = case.robot.path_joints(case.link);
    let distal: Vec<&str> = case
        .robot
        .sensed()
        .iter()
        .zip(&names)
        .filter(|(j, _)| !path.contains(j))
        .map(|(_, n)| *n)
        .collect();
    let scale_nm = f.length() * 1e-12;
    let zero: Vec<&str> = case
        .robot
        .sensed()
        .iter()
        .zip(names.iter().zip(tau))
        .filter(|(j, (_, t))| path.contains(j) && t.abs() <= scale_nm)
        .map(|(_, (n, _))| *n)
        .collect();
    if !distal.is_empty() {
        outln!("Sense nothing (they do not move {link_name}): {}", distal.join(", "));
    }
    if !zero.is_empty() {
        outln!(
            "Read zero here (the force line meets or parallels their axis): {}",
            zero.join(", ")
        );
    }
    Ok(())
}

/// Four decimals, without the "-0.0000" of a value that rounds to zero.
fn shown(value: f64) -> String {
    let text = format!("{value:.4}");
    if text.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') {
        "0.0000".to_owned()
    } else {
        text
    }
}

fn robot_info(spec: &str, package_paths: Vec<PathBuf>) -> Result<()> {
    let options = UrdfOptions {
        package_paths,
        meshes: MeshSelection::All,
    };
    let robot = load_robot(spec, Path::new("."), &options)?;
    outln!(
        "robot {}: {} links, {} joints",
        robot.name,
        robot.links.len(),
        robot.joints.len()
    );
    outln!(
        "sensed joints (order of q and tau): {}",
        robot.sensed_names().join(", ")
    );
    let candidates = robot.default_candidate_links();
    for (i, link) in robot.links.iter().enumerate() {
        let joint = link.parent_joint.map_or_else(
            || "root".to_owned(),
            |j| format!("{} ({:?})", robot.joints[j].name, robot.joints[j].kind),
        );
        outln!(
            "  link {:<24} {:>7} triangles  area {:>8.4} m²  moved by {joint}{}",
            link.name,
            link.mesh.triangles.len(),
            link.mesh.area() + 0.0, // an empty sum is -0.0
            if candidates.contains(&i) { "  [candidate]" } else { "" }
        );
    }
    Ok(())
}

fn surface(path: &Path, points: Option<usize>) -> Result<()> {
    let loaded = Scene::read(path)?.load(path)?;
    let request = SurfaceRequest {
        links: loaded.candidate_links.clone(),
        total_points: points.unwrap_or(loaded.scene.surface_points),
        seed: loaded.scene.surface_seed,
    };
    let start = std::time::Instant::now();
    let surface = Surface::sample(&loaded.robot, &request).with_context(|| format!("{}", path.display()))?;
    let elapsed = start.elapsed();
    outln!(
        "{} surface points on {} links in {:.1} ms",
        surface.len(),
        surface.stats.len(),
        elapsed.as_secs_f64() * 1e3
    );
    outln!(
        "{:<20} {:>9} {:>9} {:>7} {:>7} {:>6} {:>6} {:>7}",
        "link",
        "area m²",
        "exposed",
        "drawn",
        "buried",
        "open",
        "kept",
        "shells"
    );
    for st in &surface.stats {
        outln!(
            "{:<20} {:>9.4} {:>9.4} {:>7} {:>7} {:>6} {:>6} {:>7}",
            loaded.robot.links[st.link].name,
            st.mesh_area_m2,
            st.exposed_area_m2,
            st.drawn,
            st.buried,
            st.open_or_thin,
            st.kept,
            st.shells
        );
    }
    Ok(())
}

#[cfg(feature = "gui")]
/// Renders the app headless into a PNG.
fn screenshot(
    target: Option<&str>,
    robot: Option<&str>,
    (frame, contacts): (Option<usize>, Option<u8>),
    out: &Path,
    size: [u32; 2],
) -> Result<()> {
    let mut start = proprioscope::app::open_target_with(target, robot, &[])?;
    if let Some(n) = contacts {
        start.settings.config.contacts_at_once = usize::from(n);
    }
    if let Some(session) = &mut start.session {
        session.frame = frame;
    } else if frame.is_some() {
        bail!("--frame needs a session to show");
    }
    let image = proprioscope::app::render_headless(start, [size[0] as f32, size[1] as f32])
        .map_err(|e| anyhow::anyhow!("rendering the app headless: {e}"))?;
    if let Some(folder) = out.parent() {
        std::fs::create_dir_all(folder).with_context(|| format!("creating {}", folder.display()))?;
    }
    image.save(out).with_context(|| format!("writing {}", out.display()))?;
    outln!("wrote {} ({}×{})", out.display(), image.width(), image.height());
    Ok(())
}

#[cfg(feature = "gui")]
/// Draws what `mcap` holds for Foxglove at `at` s into the PNG `out`.
fn preview_mcap(mcap: &Path, at: f64, out: &Path, size: [u32; 2]) -> Result<()> {
    let bytes = std::fs::read(mcap).with_context(|| format!("reading {}", mcap.display()))?;
    let image = proprioscope::app::mcap_preview::render_mcap_headless(&bytes, at, [size[0] as f32, size[1] as f32])
        .map_err(|e| anyhow::anyhow!("{}: {e}", mcap.display()))?;
    image.save(out).with_context(|| format!("writing {}", out.display()))?;
    outln!("wrote {} ({}×{})", out.display(), image.width(), image.height());
    Ok(())
}

#[cfg(feature = "gui")]
/// Opens the app: on the built-in LWR with a push, or on `target`.
fn run_app(
    target: Option<&str>,
    robot: Option<&str>,
    package_paths: &[PathBuf],
    (live, serve): (Option<String>, Option<String>),
) -> Result<()> {
    use proprioscope::app::ProprioscopeApp;
    let mut start = proprioscope::app::open_target_with(target, robot, package_paths)?;
    start.live = live;
    start.serve = serve;
    let options = eframe::NativeOptions {
        viewport: eframe::egui::ViewportBuilder::default()
            .with_inner_size([1400.0, 900.0])
            .with_title("Proprioscope"),
        ..eframe::NativeOptions::default()
    };
    eframe::run_native(
        "Proprioscope",
        options,
        Box::new(move |cc| Ok(Box::new(ProprioscopeApp::from_start(cc, start)))),
    )
    .map_err(|e| anyhow::anyhow!("the window could not be opened: {e}"))
}

fn export_assets(root: &Path) -> Result<()> {
    let path = root.join(LWR4PLUS_GLB_PATH);
    let bytes = lwr4plus_glb_generated();
    if let Some(folder) = path.parent() {
        std::fs::create_dir_all(folder).with_context(|| format!("creating {}", folder.display()))?;
    }
    std::fs::write(&path, &bytes).with_context(|| format!("writing {}", path.display()))?;
    outln!("wrote {} ({} bytes)", path.display(), bytes.len());
    let layout = root.join(proprioscope::io::foxglove::layout::LAYOUT_PATH);
    let text = proprioscope::io::foxglove::layout::layout_text();
    std::fs::write(&layout, &text).with_context(|| format!("writing {}", layout.display()))?;
    outln!("wrote {} ({} bytes)", layout.display(), text.len());
    Ok(())
}

#[cfg(feature = "gui")]
/// Records the scripted session of `record-demo`.
fn record_demo(out: &Path, rate: f64, seconds: Option<f64>) -> Result<()> {
    use proprioscope::app::{Model, Push, StartSettings, ViewOptions};
    use proprioscope::io::session::Recorder;
    if !(rate.is_finite() && rate > 0.0) {
        bail!("--rate {rate}: give a positive number of frames per second");
    }
    let robot = proprioscope::core::robot::builtin::lwr4plus_generated()?;
    let link = robot.link_id("lwr_5_link")?;
    let joints: Vec<String> = robot.sensed().iter().map(|&j| robot.joints[j].name.clone()).collect();
    let push = Some(Push {
        link,
        point_in_link: DVec3::new(0.06, 0.0, 0.1),
        inward_normal_in_link: DVec3::new(-1.0, 0.0, 0.0),
        force_newtons: 12.0,
    });
    let settings = StartSettings {
        config: proprioscope::core::config::estimator::EstimatorConfig {
            surface_points: 1000,
            ..proprioscope::core::config::estimator::EstimatorConfig::default()
        },
        ..StartSettings::default()
    };
    let mut model = Model::from_start(robot, vec![0.0; joints.len()], push, settings, ViewOptions::default());
    let mut recorder = Recorder::create(out, "lwr4plus", &joints)?;
    let started = std::time::Instant::now();
    // Tell a watching test when the first frame is on disk.
    let mut announced = false;
    for i in 0u32.. {
        let t = f64::from(i) / rate;
        if seconds.is_some_and(|s| t > s) {
            break;
        }
        let wait = t - started.elapsed().as_secs_f64();
        if wait > 0.0 {
            std::thread::sleep(std::time::Duration::from_secs_f64(wait));
        }
        for (j, q) in model.q.iter_mut().enumerate() {
            *q = 0.5 * (t + 0.3 * j as f64).sin();
        }
        model.noise_seed = u64::from(i);
        recorder.write(&proprioscope::app::recorder::interactive_frame(&model, t))?;
        if !announced {
            outln!("recording {}", out.display());
            std::io::Write::flush(&mut std::io::stdout())?;
            announced = true;
        }
    }
    let frames = recorder.finish()?;
    outln!("wrote {frames} frames to {}", out.display());
    Ok(())
}

/// Without the GUI (`--no-default-features`) the commands that draw say so.
#[cfg(not(feature = "gui"))]
fn without_gui(what: &str) -> Result<()> {
    bail!(
        "{what} needs the desktop app, and this proprioscope was built without it (--no-default-features): build it with the default features"
    )
}

#[cfg(not(feature = "gui"))]
fn screenshot(_: Option<&str>, _: Option<&str>, _: (Option<usize>, Option<u8>), _: &Path, _: [u32; 2]) -> Result<()> {
    without_gui("screenshot")
}

#[cfg(not(feature = "gui"))]
fn run_app(_: Option<&str>, _: Option<&str>, _: &[PathBuf], _: (Option<String>, Option<String>)) -> Result<()> {
    without_gui("view")
}

#[cfg(not(feature = "gui"))]
fn preview_mcap(_: &Path, _: f64, _: &Path, _: [u32; 2]) -> Result<()> {
    without_gui("preview-mcap")
}

#[cfg(not(feature = "gui"))]
fn record_demo(_: &Path, _: f64, _: Option<f64>) -> Result<()> {
    without_gui("record-demo")
}
