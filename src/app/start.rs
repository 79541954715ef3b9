//! Start-up: what the app opens on (scene, URDF, robot, session), and
//! the headless harness behind `proprioscope screenshot` and the UI tests.

use super::{DVec3, LinkId, ProprioscopeApp, Push, Robot, StartSettings, ViewOptions, egui, timeline};

/// Renders the app headless (Mesa's software Vulkan or a GPU, no window):
/// runs frames until the estimate for the current model has arrived, then
/// returns the image. The path of `proprioscope screenshot` and the UI tests.
pub fn render_headless(start: AppStart, size: [f32; 2]) -> Result<image::RgbaImage, String> {
    let mut harness = headless_harness(start, size);
    // Names from the user's files (links, joints, paths) may hold
    // characters no bundled font has: a box, as in the app, not a panic
    // (the UI tests keep the harness's panic, to catch our own text).
    harness
        .ctx
        .set_missing_glyph_policy(egui::epaint::text::MissingGlyphPolicy::Tofu);
    settle(&mut harness)?;
    // A session that failed to load in the background is an error here,
    // not a picture of the scene it would have replaced.
    if let Some(error) = &harness.state().error {
        return Err(error.clone());
    }
    harness.render()
}

/// The app in a headless harness (wgpu), not yet settled.
#[must_use]
pub fn headless_harness(start: AppStart, size: [f32; 2]) -> egui_kittest::Harness<'static, ProprioscopeApp> {
    egui_kittest::Harness::builder()
        .with_size(egui::vec2(size[0], size[1]))
        .wgpu()
        .build_eframe(move |cc| ProprioscopeApp::from_start(cc, start))
}

/// What the app opens on.
#[derive(Debug, Clone)]
pub struct AppStart {
    /// How the robot was named (built-in name or URDF path), for saving.
    pub robot_spec: String,
    /// The robot.
    pub robot: Robot,
    /// Sensed joint positions, rad.
    pub q: Vec<f64>,
    /// The push, if any.
    pub push: Option<Push>,
    /// Estimator and sensor settings.
    pub settings: StartSettings,
    /// A session to open once the app runs (loaded in the background).
    pub session: Option<timeline::SessionTarget>,
    /// Folders for `package://` URIs.
    pub package_paths: Vec<std::path::PathBuf>,
    /// An address to listen on for a live session.
    pub live: Option<String>,
    /// An address to serve Foxglove's WebSocket protocol on (`--serve`).
    pub serve: Option<String>,
    /// The robot was named (a scene, URDF or built-in name), not the
    /// default: sessions that name no robot may be shown on it.
    pub robot_chosen: bool,
}

/// Whether `path` is a recorded session: a CSV file, or JSON that says it
/// is a `contact-session`.
#[must_use]
pub fn is_session_file(path: &std::path::Path) -> bool {
    use std::io::Read as _;
    let extension = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
    match extension.as_deref() {
        Some("csv" | "mcap" | "bag") => true,
        Some("json") => {
            let mut head = [0u8; 512];
            let read = std::fs::File::open(path)
                .and_then(|mut f| f.read(&mut head))
                .unwrap_or(0);
            String::from_utf8_lossy(head.get(..read).unwrap_or_default()).contains("contact-session")
        }
        _ => false,
    }
}

/// The default scene (`None`), a scene file (`.json`, with its push and
/// settings), a URDF or a built-in robot name.
pub fn open_target(target: Option<&str>) -> anyhow::Result<AppStart> {
    open_target_with(target, None, &[])
}

/// [`open_target`], where `target` may also be a recorded session (opened
/// on the default scene, then loaded in the background), with a robot
/// override for sessions and folders for `package://` URIs.
pub fn open_target_with(
    target: Option<&str>,
    robot: Option<&str>,
    package_paths: &[std::path::PathBuf],
) -> anyhow::Result<AppStart> {
    use crate::io::builtin::load_robot;
    use crate::io::urdf::UrdfOptions;
    use std::path::Path;
    if let Some(t) = target
        && is_session_file(Path::new(t))
    {
        if robot.is_none() && crate::io::open::names_no_robot(Path::new(t)) {
            anyhow::bail!(
                "{t} names no robot (CSV sessions and recordings do not): give it with --robot URDF (or a built-in name)"
            );
        }
        let mut start = open_target_with(None, None, package_paths)?;
        start.session = Some(timeline::SessionTarget {
            path: t.into(),
            robot: robot.map(str::to_owned),
            frame: None,
        });
        return Ok(start);
    }
    Ok(match target {
        None => {
            let robot = load_robot("lwr4plus", Path::new("."), &UrdfOptions::default())?;
            let (q, push) = ProprioscopeApp::default_scene(&robot);
            AppStart {
                robot_spec: "lwr4plus".to_owned(),
                robot,
                q,
                push,
                settings: StartSettings::default(),
                session: None,
                live: None,
                package_paths: package_paths.to_vec(),
                robot_chosen: false,
                serve: None,
            }
        }
        Some(t) if t.to_ascii_lowercase().ends_with(".json") => scene_start(Path::new(t), package_paths)?,
        Some(t) => {
            let options = UrdfOptions {
                package_paths: package_paths.to_vec(),
                ..UrdfOptions::default()
            };
            let robot = load_robot(t, Path::new("."), &options)?;
            let q = vec![0.0; robot.sensed().len()];
            AppStart {
                robot_spec: if crate::io::builtin::is_builtin(t) {
                    t.to_owned()
                } else {
                    absolute_spec(Path::new(t))
                },
                robot,
                q,
                push: None,
                settings: StartSettings::default(),
                session: None,
                live: None,
                package_paths: package_paths.to_vec(),
                robot_chosen: true,
                serve: None,
            }
        }
    })
}

/// What a scene file opens on: its robot, pose, push and every setting.
fn scene_start(path: &std::path::Path, package_paths: &[std::path::PathBuf]) -> anyhow::Result<AppStart> {
    use crate::io::scene::Scene;
    use std::path::Path;
    let loaded = Scene::read(path)?.load(path)?;
    let in_link = |p: crate::io::scene::ResolvedPush| {
        let link_from_world = loaded.pose.world_from_link.get(p.link)?.inverse();
        Some(Push {
            link: p.link,
            point_in_link: link_from_world.transform_point3(p.point_world),
            inward_normal_in_link: link_from_world.transform_vector3(p.force_world.try_normalize()?),
            force_newtons: p.force_world.length(),
        })
    };
    let push = loaded.push.and_then(in_link);
    let second_push = loaded.second_push.and_then(in_link);
    let settings = StartSettings {
        config: loaded.scene.config(),
        noise: (loaded.scene.noise.sigma_newton_metres, loaded.scene.noise.seed),
        candidate_links: loaded
            .scene
            .candidate_links
            .is_some()
            .then(|| loaded.candidate_links.clone()),
        other_joints: loaded.scene.other_joints.iter().map(|(k, v)| (k.clone(), *v)).collect(),
        view: loaded.scene.view.map(|v| ViewOptions {
            log_scale: v.log_scale,
            threshold: v.threshold,
            red_green: v.red_green,
            show_points: v.candidate_points,
            show_axes: v.joint_axes,
            layer: v.layer,
        }),
        title: (loaded.scene.name.clone(), loaded.scene.description.clone()),
        second_push,
    };
    let folder = path.parent().unwrap_or(Path::new("."));
    let mut package_paths = package_paths.to_vec();
    package_paths.extend(
        loaded
            .scene
            .package_paths
            .iter()
            .map(|p| crate::io::scene::normalized_path(&folder.join(p))),
    );
    let spec = if crate::io::builtin::is_builtin(&loaded.scene.robot) {
        loaded.scene.robot.clone()
    } else {
        absolute_spec(&folder.join(&loaded.scene.robot))
    };
    Ok(AppStart {
        robot_spec: spec,
        q: loaded.scene.q.clone(),
        robot: loaded.robot,
        push,
        settings,
        session: None,
        live: None,
        package_paths,
        robot_chosen: true,
        serve: None,
    })
}

/// A URDF path as the app keeps it: absolute, so that a scene saved
/// anywhere can name it relative to itself.
fn absolute_spec(path: &std::path::Path) -> String {
    crate::io::scene::normalized_path(path).display().to_string()
}

/// Runs frames until the newest estimate has arrived (at most ~10 s), then
/// until nothing moves: a session's timeline panel grows into place over
/// a dozen frames, and a picture taken before it ends depends on how soon
/// the estimate came.
pub fn settle(harness: &mut egui_kittest::Harness<'_, ProprioscopeApp>) -> Result<(), String> {
    for _ in 0..1000 {
        harness.step();
        if harness.state().is_up_to_date() {
            harness.run_steps(2);
            // Beyond kittest's few steps it goes on until the frames are
            // still (or its hundred diagnostic steps pass): either is as
            // far as waiting helps.
            let _ = harness.try_run();
            return Ok(());
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    Err("the estimate did not arrive within 10 s".to_owned())
}

impl ProprioscopeApp {
    /// The current model as a scene file to be written at `scene_path`:
    /// everything the app shows, a URDF robot and package folders named
    /// relative to the scene's folder.
    #[must_use]
    pub fn to_scene(&self, scene_path: &std::path::Path) -> crate::io::scene::Scene {
        use crate::io::scene as sc;
        let m = &self.model;
        let pose = m.pose();
        let folder = scene_path.parent().unwrap_or(std::path::Path::new("."));
        let relative = |p: &std::path::Path| sc::relative_path(p, folder).display().to_string();
        let builtin = crate::io::builtin::is_builtin(&self.robot_spec);
        let scene_push = |(link, point, force): (LinkId, DVec3, DVec3)| sc::Push {
            link: m.robot.links.get(link).map(|l| l.name.clone()).unwrap_or_default(),
            point_in_link: None,
            point_world: Some(point.to_array()),
            force_world: Some(force.to_array()),
            force_newtons: None,
        };
        sc::Scene {
            version: sc::SCENE_VERSION,
            name: m.title.0.clone(),
            description: m.title.1.clone(),
            robot: if builtin {
                self.robot_spec.clone()
            } else {
                relative(std::path::Path::new(&self.robot_spec))
            },
            package_paths: self.files.package_paths.iter().map(|p| relative(p)).collect(),
            sensed_joints: (!builtin).then(|| m.robot.sensed_names().into_iter().map(str::to_owned).collect()),
            q: m.q.clone(),
            other_joints: m.other_joints.iter().cloned().collect(),
            candidate_links: (m.candidate_links != m.robot.default_candidate_links()).then(|| {
                m.candidate_links
                    .iter()
                    .map(|&l| m.robot.links[l].name.clone())
                    .collect()
            }),
            surface_points: m.config.surface_points,
            surface_seed: m.config.surface_seed,
            push: m.push_world(&pose).map(scene_push),
            second_push: m.second_push_world(&pose).map(scene_push),
            noise: sc::Noise {
                sigma_newton_metres: m.noise_sigma,
                seed: m.noise_seed,
            },
            estimator: sc::EstimatorSettings::from_config(&m.config),
            view: Some(sc::View {
                log_scale: m.view.log_scale,
                threshold: m.view.threshold,
                red_green: m.view.red_green,
                candidate_points: m.view.show_points,
                joint_axes: m.view.show_axes,
                layer: m.view.layer,
            }),
        }
    }

    /// Writes the current scene as JSON.
    pub fn save(&mut self, path: &std::path::Path) {
        let result = self
            .to_scene(path)
            .to_json()
            .map_err(|e| e.to_string())
            .and_then(|json| std::fs::write(path, json).map_err(|e| e.to_string()));
        self.error = result.err().map(|e| format!("could not save {}: {e}", path.display()));
    }
}
