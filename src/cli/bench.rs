//! `proprioscope bench`: speed against accuracy for estimator
//! configurations, on seeded random contacts with sensor noise.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, Result, anyhow};
use glam::DVec3;
use proprioscope::core::config::limits;
use proprioscope::core::estimate::estimator::Estimator;
use proprioscope::core::estimate::settings::{EstimatorSettings, Mode, ParticleSettings, Sampling};
use proprioscope::core::eval::metrics::{FrameOutcome, Metrics, metrics, percentile};
use proprioscope::core::numerics::rng::Rng;
use proprioscope::core::robot::kinematics::RobotPose;
use proprioscope::core::robot::model::{JointKind, Robot};
use proprioscope::core::robot::torque::joint_torques;
use proprioscope::core::surface::sampling::{Surface, SurfaceRequest};
use proprioscope::io::builtin::load_robot;
use proprioscope::io::urdf::{MeshSelection, UrdfOptions};

/// Options of `bench`.
#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    /// URDF robots to bench besides the built-in LWR (repeatable).
    #[arg(long)]
    pub urdf: Vec<PathBuf>,
    /// Extra folder for `package://` URIs (repeatable).
    #[arg(long = "package-path")]
    pub package_paths: Vec<PathBuf>,
    /// Random contacts per configuration (valid: 1 to 1000000).
    #[arg(long, default_value_t = 100, value_parser = super::counted(&limits::CONTACTS))]
    pub contacts: usize,
    /// Sensor noise on the contacts' torques, N·m (valid: [0, 100]).
    #[arg(long, default_value_t = 0.05, value_parser = super::within(&limits::NOISE))]
    pub noise: f64,
    /// Seed of the contacts.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// A few small configurations only.
    #[arg(long)]
    pub quick: bool,
    /// Recorded sessions to time frame by frame and to estimate at each
    /// surface seed (repeatable; sessions with no-contact frames show the
    /// 99th percentile that matters).
    #[arg(long)]
    pub session: Vec<PathBuf>,
    /// Surface seeds for the sessions.
    #[arg(long, value_delimiter = ',', default_value = "0,1,2,3,4")]
    pub seeds: Vec<u64>,
    /// Sessions: also run the refined estimator (frames alone) at these
    /// numbers of surface points, a row each, to show what a coarser
    /// surface saves and costs (e.g. `500,1000,2000`).
    #[arg(long, value_delimiter = ',', value_parser = clap::value_parser!(u64).range(10..=1_000_000))]
    pub session_points: Vec<u64>,
    /// Only the sessions (no random contacts).
    #[arg(long)]
    pub sessions_only: bool,
    /// Sessions: run each estimator over the session this many times in a
    /// row per surface seed and time each frame by its fastest run: the
    /// frame's own cost on a warm estimator, less what else the machine
    /// did meanwhile (1: each frame timed once).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub repeat: u32,
    /// Where to write the plot of update time against error (PNG); none
    /// is written unless asked for (or with --doc, which links it).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Replace the text between `<!-- bench:begin -->` and
    /// `<!-- bench:end -->` in this Markdown file (`docs/validation.md`)
    /// with the table and the plot.
    #[arg(long)]
    pub doc: Option<PathBuf>,
    /// Instead of the tables: synthesise a recording this long, s (presses
    /// on links 4–7, σ the noise drawn) and smooth it at each of
    /// `--threads`, reporting wall time, frames per second, the real-time
    /// factor, peak memory and the smoothed accuracy (valid: (0, 3600] s).
    #[arg(long, value_parser = super::within(&limits::SECONDS))]
    pub recording: Option<f64>,
    /// `--recording`'s frame rate, Hz (valid: (0, 10000] Hz).
    #[arg(long, default_value_t = 1000.0, value_parser = super::within(&limits::RATE_HZ))]
    pub rate: f64,
    /// `--recording`'s thread counts (default: 1, 2 and every core).
    #[arg(long, value_delimiter = ',', value_parser = super::counted(&limits::THREADS))]
    pub threads: Vec<usize>,
    /// `--recording`: memory the smoothing may take, MiB (see `estimate
    /// --memory`; valid: 64 to 1048576).
    #[arg(long, default_value_t = proprioscope::core::config::estimator::DEFAULT_MEMORY_MIB, value_parser = super::counted(&limits::MEMORY_MIB))]
    pub memory: usize,
    /// A TrueType font for the plot's text.
    #[arg(long, default_value = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf")]
    pub font: PathBuf,
}

/// One estimator configuration.
#[derive(Debug, Clone)]
struct Config {
    label: String,
    surface_points: usize,
    mode: Mode,
    phases: bool,
    sigma: f64,
    threads: usize,
}

/// A seeded random push and what the sensors read.
struct Contact {
    joint_positions: Vec<f64>,
    tau: Vec<f64>,
    link: usize,
    point_world: DVec3,
    force_world: DVec3,
}

/// One row of the table.
struct Row {
    robot: String,
    config: Config,
    median_us: f64,
    metrics: Metrics,
}

fn configs(quick: bool) -> Vec<Config> {
    let exact = |n: usize, phases: bool, sigma: f64, threads: usize| Config {
        label: format!(
            "exact{}{}",
            if phases { " + phases" } else { "" },
            if threads > 1 {
                format!(", {threads} threads")
            } else {
                String::new()
            }
        ),
        surface_points: n,
        mode: Mode::Exact,
        phases,
        sigma,
        threads,
    };
    let particles = |n: usize, random: bool| Config {
        label: format!("particles, {}", if random { "random" } else { "deterministic m = 5" }),
        surface_points: n / 5,
        mode: Mode::Particles(ParticleSettings {
            sampling: if random {
                Sampling::Random { count: n, seed: 7 }
            } else {
                Sampling::Deterministic {
                    magnitudes_per_point: 5,
                }
            },
        }),
        phases: false,
        sigma: 0.05,
        threads: 1,
    };
    if quick {
        return vec![
            exact(1000, false, 0.05, 1),
            exact(5000, false, 0.05, 1),
            particles(18_000, false),
            particles(18_000, true),
        ];
    }
    let mut out: Vec<Config> = [200, 1000, 5000, 20_000, 100_000]
        .iter()
        .map(|&n| exact(n, false, 0.05, 1))
        .collect();
    out.push(exact(100_000, false, 0.05, 2));
    out.push(exact(5000, true, 0.05, 1));
    out.push(Config {
        label: "exact, σ = 0.2".to_owned(),
        ..exact(5000, false, 0.2, 1)
    });
    for n in [18_000, 30_000, 50_000] {
        out.push(particles(n, false));
        out.push(particles(n, true));
    }
    out.push(Config {
        label: "particles, deterministic m = 5 + phases".to_owned(),
        phases: true,
        ..particles(23_025, false)
    });
    out
}

/// Seeded contacts: a configuration uniform within the joint limits, a
/// point uniform over the exposed surface (a dense sampling of its own),
/// a push of 3–30 N along the inward normal, noise on every joint.
fn contacts(robot: &Robot, count: usize, noise: f64, seed: u64) -> Result<Vec<Contact>> {
    let truth = Surface::sample(
        robot,
        &SurfaceRequest {
            links: robot.default_candidate_links(),
            total_points: 20_000,
            seed: seed.wrapping_add(1000),
        },
    )?;
    let mut rng = Rng::new(seed);
    let mut out = Vec::with_capacity(count);
    for _ in 0..count {
        let q: Vec<f64> = robot
            .sensed()
            .iter()
            .map(|&j| {
                let joint = &robot.joints[j];
                match (joint.kind, joint.limits) {
                    (JointKind::Revolute | JointKind::Prismatic, Some(l)) => rng.uniform_in(l.lower, l.upper),
                    _ => rng.uniform_in(-std::f64::consts::PI, std::f64::consts::PI),
                }
            })
            .collect();
        let joint_positions = robot.joint_positions(&q, &[])?;
        let pose = RobotPose::new(robot, &joint_positions);
        let k = rng.below(truth.len());
        let link = truth.link[k];
        let point_world = pose.point_to_world(link, truth.point_in_link[k]);
        let force_world =
            pose.world_from_link[link].transform_vector3(truth.inward_normal_in_link[k]) * rng.uniform_in(3.0, 30.0);
        let mut tau = joint_torques(robot, &pose, link, point_world, force_world);
        for t in &mut tau {
            *t += noise * rng.normal();
        }
        out.push(Contact {
            joint_positions,
            tau,
            link,
            point_world,
            force_world,
        });
    }
    Ok(out)
}

fn run_config(robot: &Robot, config: &Config, contacts: &[Contact], seed: u64) -> Result<(f64, Metrics)> {
    let settings = EstimatorSettings {
        mode: config.mode,
        phase_alpha: config.phases.then_some(0.5),
        ..EstimatorSettings::exact(vec![config.sigma; robot.sensed().len()])
    };
    let request = SurfaceRequest {
        links: robot.default_candidate_links(),
        total_points: config.surface_points,
        seed,
    };
    let estimator = Estimator::new(robot, &request, settings, config.phases.then_some([200, 1000]))?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(config.threads).build()?;
    pool.install(|| -> Result<(f64, Metrics)> {
        let mut times = Vec::with_capacity(contacts.len());
        let mut outcomes = Vec::with_capacity(contacts.len());
        for c in contacts {
            let t0 = Instant::now();
            let update = estimator.update(robot, &c.joint_positions, &c.tau)?;
            times.push(t0.elapsed().as_secs_f64() * 1e6);
            let map = update.summary.map;
            outcomes.push(FrameOutcome {
                sensing_joints: robot.sensing_joints(c.link),
                p_max: update.posterior.display[map.point],
                estimated_point: map.point_world,
                estimated_force: map.force_world,
                true_point: c.point_world,
                true_force: c.force_world,
                link_correct: map.link == c.link,
                in_credible90: None,
            });
        }
        Ok((percentile(&times, 0.5), metrics(&outcomes)))
    })
}

/// Runs the command.
pub fn run(args: &BenchArgs) -> Result<()> {
    if let Some(seconds) = args.recording {
        return super::bench_recording::run(&super::bench_recording::RecordingBench {
            seconds,
            rate_hz: args.rate,
            noise: args.noise,
            seed: args.seed,
            threads: args.threads.clone(),
            memory_mib: args.memory,
        });
    }
    // The document's table and plot are committed: quick figures (fewer
    // contacts and configurations) must not replace them.
    if args.quick && args.doc.is_some() {
        return Err(anyhow!(
            "--quick with --doc would put a quick run's figures in the document and screenshots/bench.png: drop --quick, or write the plot elsewhere with --plot"
        ));
    }
    let mut robots = vec![load_robot("lwr4plus", Path::new("."), &UrdfOptions::default())?];
    for urdf in &args.urdf {
        let options = UrdfOptions {
            package_paths: args.package_paths.clone(),
            meshes: MeshSelection::All,
        };
        robots.push(load_robot(&urdf.to_string_lossy(), Path::new("."), &options)?);
    }
    let mut rows = Vec::new();
    let mut out = String::new();
    for path in &args.session {
        let sessions = super::bench_sessions::SessionBench {
            package_paths: &args.package_paths,
            session_points: &args.session_points,
            seeds: &args.seeds,
            noise: args.noise,
            repeat: args.repeat,
        };
        out.push_str(&super::bench_sessions::session_table(path, &sessions)?);
        out.push('\n');
    }
    if args.sessions_only {
        outln!("{out}");
        return Ok(());
    }
    for robot in &robots {
        let contacts = contacts(robot, args.contacts, args.noise, args.seed)?;
        for config in configs(args.quick) {
            log::info!("{}: {} N = {} …", robot.name, config.label, particles_of(&config));
            let (median_us, metrics) = run_config(robot, &config, &contacts, args.seed)?;
            rows.push(Row {
                robot: robot.name.clone(),
                config,
                median_us,
                metrics,
            });
        }
    }
    let table = format!("{out}{}", table(&rows, args));
    outln!("{table}");
    let plot_path = args
        .plot
        .clone()
        .or_else(|| args.doc.as_ref().map(|_| PathBuf::from("screenshots/bench.png")));
    if let Some(path) = &plot_path {
        plot(&rows, path, &args.font)?;
        log::info!("wrote {}", path.display());
    }
    if let Some(doc) = &args.doc {
        let text = std::fs::read_to_string(doc).with_context(|| format!("reading {}", doc.display()))?;
        let (begin, end) = ("<!-- bench:begin -->", "<!-- bench:end -->");
        let (Some(i), Some(j)) = (text.find(begin), text.find(end)) else {
            return Err(anyhow!("{}: no {begin} … {end} section to replace", doc.display()));
        };
        // The plot named from the document's folder.
        let plot = plot_path.as_deref().unwrap_or(Path::new("screenshots/bench.png"));
        let folder = doc.parent().unwrap_or(Path::new("."));
        let link = proprioscope::io::scene::relative_path(
            &proprioscope::io::scene::normalized_path(&std::env::current_dir()?.join(plot)),
            &proprioscope::io::scene::normalized_path(&std::env::current_dir()?.join(folder)),
        );
        let section = format!(
            "{begin}\n{table}\n![Update time against position error]({})\n",
            link.display()
        );
        let (true, Some(before), Some(after)) = (i <= j, text.get(..i), text.get(j..)) else {
            return Err(anyhow!("{}: {end} comes before {begin}", doc.display()));
        };
        let updated = format!("{before}{section}{after}");
        std::fs::write(doc, updated).with_context(|| format!("writing {}", doc.display()))?;
        log::info!("updated {}", doc.display());
    }
    Ok(())
}

/// N as the thesis counts it: surface points in exact mode, particles otherwise.
fn particles_of(config: &Config) -> usize {
    match config.mode {
        Mode::Exact => config.surface_points,
        Mode::Particles(ParticleSettings {
            sampling: Sampling::Random { count, .. },
        }) => count,
        Mode::Particles(ParticleSettings {
            sampling: Sampling::Deterministic { magnitudes_per_point },
        }) => config.surface_points * magnitudes_per_point,
    }
}

fn table(rows: &[Row], args: &BenchArgs) -> String {
    let mut out = format!(
        "{} seeded contacts per row (seed {}): a pose uniform within the joint limits, a point uniform over the exposed surface, a push of 3–30 N along the inward normal, sensor noise σ = {} N·m; force range 1–30 N; vector loops on {}.\n\n",
        args.contacts,
        args.seed,
        args.noise,
        proprioscope::core::numerics::simd::vector_unit()
    );
    out.push_str("| robot | mode | N | surface points | σ [N·m] | threads | median update [µs] | updates/s | median pos. error [mm] | p90 [mm] | median force error [N] | p90 [N] | link right |\n");
    out.push_str("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for r in rows {
        let m = &r.metrics;
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {:.0} | {:.0} | {:.1} | {:.1} | {:.2} | {:.2} | {:.0} % |",
            r.robot,
            r.config.label,
            particles_of(&r.config),
            r.config.surface_points,
            r.config.sigma,
            r.config.threads,
            r.median_us,
            1e6 / r.median_us,
            m.position_median_m * 1e3,
            m.position_p90_m * 1e3,
            m.force_median_newtons,
            m.force_p90_newtons,
            m.link_accuracy * 100.0
        );
    }
    out
}

fn plot(rows: &[Row], path: &Path, font: &Path) -> Result<()> {
    use plotters::prelude::*;
    let bytes = std::fs::read(font).with_context(|| {
        format!(
            "reading the font {} (Debian: apt-get install fonts-dejavu-core; or give --font)",
            font.display()
        )
    })?;
    // The plotting library keeps registered fonts for the program's life.
    let bytes: &'static [u8] = Vec::leak(bytes);
    plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
        .map_err(|_| anyhow!("{}: not a usable font", font.display()))?;
    if let Some(folder) = path.parent() {
        std::fs::create_dir_all(folder)?;
    }
    let root = BitMapBackend::new(path, (1100, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let (t_lo, t_hi) = rows.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
        (lo.min(r.median_us), hi.max(r.median_us))
    });
    let e_hi = rows
        .iter()
        .map(|r| r.metrics.position_median_m * 1e3)
        .fold(0.0, f64::max);
    let mut chart = ChartBuilder::on(&root)
        .caption("Update time against median position error", ("sans-serif", 26))
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d((t_lo * 0.5..t_hi * 2.0).log_scale(), 0.0..e_hi * 1.15 + 1.0)
        .map_err(|e| anyhow!("{e}"))?;
    chart
        .configure_mesh()
        .x_desc("median update time [µs] (log scale)")
        .x_labels(8)
        .x_label_formatter(&|v| format!("{v:.0}"))
        .light_line_style(WHITE)
        .y_desc("median position error [mm]")
        .label_style(("sans-serif", 16))
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    let font = ("sans-serif", 13).into_font();
    let area = chart.plotting_area().get_pixel_range();
    let points: Vec<(i32, i32)> = rows
        .iter()
        .map(|r| chart.backend_coord(&(r.median_us, r.metrics.position_median_m * 1e3)))
        .collect();
    // Boxes (left, top, right, bottom) of the labels placed so far.
    let mut placed: Vec<(i32, i32, i32, i32)> = Vec::new();
    for (r, &(px, py)) in rows.iter().zip(&points) {
        let colour = match r.config.mode {
            Mode::Exact => BLUE,
            Mode::Particles(ParticleSettings {
                sampling: Sampling::Deterministic { .. },
            }) => GREEN,
            Mode::Particles(ParticleSettings {
                sampling: Sampling::Random { .. },
            }) => RED,
        };
        let at = (r.median_us, r.metrics.position_median_m * 1e3);
        let many_robots = rows.iter().any(|o| o.robot != r.robot);
        let label = format!(
            "{} N={}{}",
            r.config.label,
            particles_of(&r.config),
            if many_robots {
                format!(" ({})", r.robot)
            } else {
                String::new()
            }
        );
        let (w, h) = root
            .estimate_text_size(&label, &TextStyle::from(font.clone()))
            .map_or((7 * 40, 14), |(w, h)| {
                (i32::try_from(w).unwrap_or(280), i32::try_from(h).unwrap_or(14))
            });
        let (dx, dy) = label_offset((px, py), (w, h), (&area.0, &area.1), &placed, &points);
        placed.push((px + dx, py + dy, px + dx + w, py + dy + h));
        chart
            .draw_series(std::iter::once(
                EmptyElement::at(at)
                    + Circle::new((0, 0), 6, colour.filled())
                    + Text::new(label, (dx, dy), font.clone()),
            ))
            .map_err(|e| anyhow!("{e}"))?;
    }
    root.present().map_err(|e| anyhow!("{e}"))?;
    Ok(())
}

/// A box in pixels: left, top, right, bottom.
type PixelBox = (i32, i32, i32, i32);

/// Where a `w`×`h` label goes beside the point at `(px, py)`: the first of
/// eight places (right or left of the point, below or above, then one
/// line farther) that stays inside the plot `area` and clear of the
/// labels `placed` so far and of every point's dot; else the first that
/// stays inside; else right of the point. The picture must be readable
/// whatever the figures are.
fn label_offset(
    (px, py): (i32, i32),
    (w, h): (i32, i32),
    area: (&std::ops::Range<i32>, &std::ops::Range<i32>),
    placed: &[PixelBox],
    points: &[(i32, i32)],
) -> (i32, i32) {
    let candidates = [
        (9, 4),
        (9, -4 - h),
        (-9 - w, 4),
        (-9 - w, -4 - h),
        (9, 8 + h),
        (9, -8 - 2 * h),
        (-9 - w, 8 + h),
        (-9 - w, -8 - 2 * h),
    ];
    let inside = |(dx, dy): (i32, i32)| {
        let (left, top) = (px + dx, py + dy);
        left >= area.0.start && left + w <= area.0.end && top >= area.1.start && top + h <= area.1.end
    };
    let clear = |(dx, dy): (i32, i32)| {
        let (left, top) = (px + dx, py + dy);
        let (right, bottom) = (left + w, top + h);
        placed
            .iter()
            .all(|&(l, t, r, b)| right <= l || left >= r || bottom <= t || top >= b)
            && points
                .iter()
                .all(|&(x, y)| x + 6 <= left || x - 6 >= right || y + 6 <= top || y - 6 >= bottom)
    };
    candidates
        .iter()
        .copied()
        .find(|&c| inside(c) && clear(c))
        .or_else(|| candidates.iter().copied().find(|&c| inside(c)))
        .unwrap_or((9, 4))
}

#[cfg(test)]
mod tests {
    use super::label_offset;

    /// Near the right edge a label goes left of its point (it was cut off
    /// there), and one that would cover a label placed before moves.
    #[test]
    fn labels_stay_inside_the_plot_and_clear_of_each_other() {
        let area = (&(100..1000), &(50..600));
        let (w, h) = (200, 14);
        assert_eq!(label_offset((300, 300), (w, h), area, &[], &[(300, 300)]), (9, 4));
        let (dx, _) = label_offset((950, 300), (w, h), area, &[], &[(950, 300)]);
        assert!(950 + dx + w <= 1000, "{dx}");
        let taken = [(309, 304, 509, 318)];
        let moved = label_offset((300, 300), (w, h), area, &taken, &[(300, 300)]);
        assert_ne!(moved, (9, 4));
        let (left, top) = (300 + moved.0, 300 + moved.1);
        assert!(left + w <= 309 || left >= 509 || top + h <= 304 || top >= 318);
    }
}
