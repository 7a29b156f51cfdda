//! The workstation window as a person uses it, on a virtual X server (Xvfb, installed by
//! `.ci/setup` with xdotool): it opens on the demo scene and shows the object and the panel
//! (read from the window's own pixels); a click on a tool button selects the tool in the
//! simulation and the probe appears under the mouse; keys save a screenshot and quit; the mouse
//! as the stylus raises a rope bump and paints a stroke, which the export (Ctrl+E) keeps.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use e2e_tests::binary;

/// A virtual X server on its own display, killed when dropped.
struct Xvfb {
    child: Child,
    display: String,
}

impl Xvfb {
    fn start() -> Self {
        assert!(
            which("Xvfb") && which("xdotool"),
            "the window tests need Xvfb and xdotool: run .ci/setup (Debian packages xvfb, xdotool)"
        );
        // Xvfb picks a free display itself and writes its number on stdout (-displayfd).
        // `-noreset`: by default the server resets when its last client disconnects, and a
        // client connecting meanwhile is refused; the tests poll with xdotool (a client that
        // connects and leaves) while the workstation opens its window, and CI once saw the
        // window fail with "Failed to open connection to X server" that way.
        let mut child = Command::new("Xvfb")
            .args([
                "-noreset",
                "-displayfd",
                "1",
                "-screen",
                "0",
                "1280x900x24",
                "-ac",
                "-nolisten",
                "tcp",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start Xvfb");
        let mut line = String::new();
        std::io::BufRead::read_line(
            &mut std::io::BufReader::new(child.stdout.take().expect("piped")),
            &mut line,
        )
        .expect("Xvfb's display number");
        let n: u32 = line
            .trim()
            .parse()
            .unwrap_or_else(|_| panic!("Xvfb said `{line}`"));
        Self {
            child,
            display: format!(":{n}"),
        }
    }

    fn xdotool(&self, args: &[&str]) {
        assert!(self.try_xdotool(args), "xdotool {args:?} failed");
    }

    /// Whether xdotool succeeded (`search` fails when no window matches).
    fn try_xdotool(&self, args: &[&str]) -> bool {
        Command::new("xdotool")
            .args(args)
            .env("DISPLAY", &self.display)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .expect("run xdotool")
            .success()
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn which(cmd: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(cmd).is_file()))
}

/// `workstation view` on the display, its output in files under `dir`.
fn view(x: &Xvfb, dir: &Path, args: &[&str]) -> Child {
    let log = std::fs::File::create(dir.join("view.log")).unwrap();
    Command::new(binary("workstation"))
        .arg("view")
        .args(args)
        .arg("--out")
        .arg(dir.join("out"))
        .env("DISPLAY", &x.display)
        .env("RUST_LOG", "info")
        .stdout(log.try_clone().unwrap())
        .stderr(log)
        .spawn()
        .expect("start workstation view")
}

fn wait_exit(child: &mut Child, dir: &Path, within: Duration) {
    let t0 = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let log = std::fs::read_to_string(dir.join("view.log")).unwrap_or_default();
            assert!(status.success(), "workstation view failed: {status}\n{log}");
            return;
        }
        if t0.elapsed() > within {
            let _ = child.kill();
            let log = std::fs::read_to_string(dir.join("view.log")).unwrap_or_default();
            panic!("workstation view did not exit within {within:?}\n{log}");
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// An RGB(A) PNG as rows of RGB.
struct Picture {
    width: usize,
    height: usize,
    rgb: Vec<[u8; 3]>,
}

impl Picture {
    fn load(path: &Path) -> Self {
        let decoder =
            png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        let channels = info.color_type.samples();
        let rgb = buf[..info.buffer_size()]
            .chunks(channels)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        Self {
            width: info.width as usize,
            height: info.height as usize,
            rgb,
        }
    }

    /// Fraction of pixels in `[x0, x1) × [y0, y1)` for which `f` holds.
    fn fraction(
        &self,
        (x0, x1): (usize, usize),
        (y0, y1): (usize, usize),
        f: impl Fn([u8; 3]) -> bool,
    ) -> f64 {
        let (x1, y1) = (x1.min(self.width), y1.min(self.height));
        let mut n = 0;
        for y in y0..y1 {
            for x in x0..x1 {
                n += usize::from(f(self.rgb[y * self.width + x]));
            }
        }
        n as f64 / ((x1 - x0) * (y1 - y0)).max(1) as f64
    }
}

fn state(path: &Path) -> Option<serde_json::Value> {
    serde_json::from_str(&std::fs::read_to_string(path).ok()?).ok()
}

#[test]
fn the_window_shows_the_object_and_the_panel_in_its_own_pixels() {
    let _slot = e2e_tests::busy_slot();
    let x = Xvfb::start();
    let dir = tempfile::tempdir().unwrap();
    let shot = dir.path().join("window.png");
    let state_file = dir.path().join("state.json");
    let mut child = view(
        &x,
        dir.path(),
        &[
            "--screenshot",
            shot.to_str().unwrap(),
            "--frames",
            "20",
            "--state",
            state_file.to_str().unwrap(),
        ],
    );
    wait_exit(&mut child, dir.path(), Duration::from_secs(120));
    let pic = Picture::load(&shot);
    assert_eq!((pic.width, pic.height), (1280, 800), "the window's size");
    let s = state(&state_file).expect("the state file");
    let view = s.get("view").and_then(|v| v.as_array()).expect("view rect");
    let vx = view[0].as_f64().unwrap() as usize;
    assert!(
        (200..600).contains(&vx),
        "the panel is on the left, the view from x = {vx}"
    );
    // The panel: its grey background with light text on it.
    let panel_bg = pic.fraction((0, vx - 4), (0, pic.height), |[r, g, b]| {
        r.abs_diff(g) < 4 && g.abs_diff(b) < 4 && (20..40).contains(&r)
    });
    let text = pic.fraction((0, vx - 4), (0, 300), |[r, g, b]| {
        r > 150 && g > 150 && b > 150
    });
    assert!(
        panel_bg > 0.5,
        "panel background covers {panel_bg:.2} of the panel"
    );
    assert!(text > 0.01, "panel text covers {text:.3} of its top");
    // The view: the lit grey spheres fill a good part of its middle, the background the rest.
    let (w, h) = (pic.width - vx, pic.height);
    let middle = ((vx + w / 4, vx + 3 * w / 4), (h / 4, 3 * h / 4));
    let object = pic.fraction(middle.0, middle.1, |[r, g, b]| {
        r > 90 && r.abs_diff(g) < 12 && g.abs_diff(b) < 12
    });
    let background = pic.fraction((vx, pic.width), (0, h), |[r, g, b]| {
        r < 40 && g < 40 && b < 48 && b > r
    });
    assert!(
        object > 0.3,
        "the object covers {object:.2} of the view's middle"
    );
    assert!(
        background > 0.2,
        "the background covers {background:.2} of the view"
    );
    assert_eq!(s.get("tool").and_then(|t| t.as_str()), Some("touch"));
    assert!(s.get("points").and_then(|p| p.as_f64()).unwrap() > 1000.0);
}

#[test]
fn a_click_on_a_tool_button_selects_it_and_the_probe_follows_the_mouse() {
    let _slot = e2e_tests::busy_slot();
    let x = Xvfb::start();
    let dir = tempfile::tempdir().unwrap();
    let state_file = dir.path().join("state.json");
    let mut child = view(
        &x,
        dir.path(),
        &[
            "--frames",
            "1000000",
            "--state",
            state_file.to_str().unwrap(),
        ],
    );
    // Where the button is, from the window's own account of its layout.
    let t0 = Instant::now();
    let (bx, by, view_rect) = loop {
        assert!(
            t0.elapsed() < Duration::from_secs(90),
            "the window did not come up"
        );
        assert!(
            child.try_wait().unwrap().is_none(),
            "workstation view exited early"
        );
        if let Some(s) = state(&state_file)
            && let Some(b) = s
                .get("tool_buttons")
                .and_then(|b| b.get("probe_push"))
                .and_then(|b| b.as_array())
            && s.get("frames").and_then(|f| f.as_f64()).unwrap_or(0.0) >= 3.0
        {
            let n = |i: usize| b[i].as_f64().unwrap();
            let v: Vec<f64> = s
                .get("view")
                .unwrap()
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            break (n(0) + 0.5 * n(2), n(1) + 0.5 * n(3), v);
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    x.xdotool(&[
        "mousemove",
        &format!("{bx:.0}"),
        &format!("{by:.0}"),
        "click",
        "1",
    ]);
    let t0 = Instant::now();
    loop {
        let tool = state(&state_file)
            .and_then(|s| s.get("tool").and_then(|t| t.as_str().map(String::from)));
        if tool.as_deref() == Some("probe_push") {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "the simulation's tool is {tool:?} after the click"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    // Over the object the probe is drawn at the cursor: translucent blue over the grey.
    let (cx, cy) = (
        view_rect[0] + 0.55 * view_rect[2],
        view_rect[1] + 0.5 * view_rect[3],
    );
    x.xdotool(&["mousemove", &format!("{cx:.0}"), &format!("{cy:.0}")]);
    std::thread::sleep(Duration::from_millis(1500));
    focus(&x);
    x.xdotool(&["key", "F12"]);
    let out = dir.path().join("out");
    let t0 = Instant::now();
    let shot = loop {
        let found = std::fs::read_dir(&out).ok().and_then(|d| {
            d.filter_map(|e| e.ok().map(|e| e.path())).find(|p| {
                p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with("screenshot_"))
            })
        });
        if let Some(p) = found {
            std::thread::sleep(Duration::from_millis(300)); // written whole
            break p;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "F12 saved no screenshot"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    let pic = Picture::load(&shot);
    let (cx, cy) = (cx as usize, cy as usize);
    let bluish = pic.fraction((cx - 15, cx + 15), (cy - 15, cy + 15), |[r, _, b]| {
        b as i32 > r as i32 + 25
    });
    assert!(
        bluish > 0.5,
        "the probe under the mouse: {bluish:.2} of the pixels are blue"
    );
    x.xdotool(&["key", "ctrl+q"]);
    wait_exit(&mut child, dir.path(), Duration::from_secs(30));
}

#[test]
fn the_demo_opens_the_window_when_a_display_is_present_and_it_stays_on_the_result() {
    let _slot = e2e_tests::busy_slot();
    let x = Xvfb::start();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let log = std::fs::File::create(dir.path().join("view.log")).unwrap();
    let mut child = Command::new(binary("workstation"))
        .arg("demo")
        .arg("--out")
        .arg(&out)
        .env("DISPLAY", &x.display)
        .stdout(log.try_clone().unwrap())
        .stderr(log)
        .spawn()
        .expect("start workstation demo");
    let t0 = Instant::now();
    while !x.try_xdotool(&["search", "--name", "workstation demo"]) {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the demo exited without a window:\n{}",
            std::fs::read_to_string(dir.path().join("view.log")).unwrap_or_default()
        );
        assert!(t0.elapsed() < Duration::from_secs(60), "no demo window");
        std::thread::sleep(Duration::from_millis(200));
    }
    while !out.join("summary.json").exists() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the demo exited before its summary"
        );
        assert!(
            t0.elapsed() < Duration::from_secs(150),
            "the demo did not finish"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    // Finished, the window stays on the result until the person closes it.
    std::thread::sleep(Duration::from_millis(500));
    assert!(
        child.try_wait().unwrap().is_none(),
        "the window closed by itself"
    );
    x.xdotool(&[
        "search",
        "--name",
        "workstation demo",
        "windowfocus",
        "--sync",
    ]);
    x.xdotool(&["key", "ctrl+q"]);
    wait_exit(&mut child, dir.path(), Duration::from_secs(30));
    let log = std::fs::read_to_string(dir.path().join("view.log")).unwrap();
    assert!(log.contains("demo: done"), "{log}");
}

/// The points of a binary PLY as `final.ply` is written (`double x y z`, `float nx ny nz`,
/// `uchar red green blue`).
fn ply_points(path: &Path) -> Vec<([f64; 3], [u8; 3])> {
    let bytes = std::fs::read(path).unwrap();
    let end = b"end_header\n";
    let body = bytes
        .windows(end.len())
        .position(|w| w == end)
        .expect("a PLY header")
        + end.len();
    let header = std::str::from_utf8(&bytes[..body]).unwrap();
    assert!(header.contains("binary_little_endian"), "{header}");
    assert!(header.contains("property uchar red"), "{header}");
    let n: usize = header
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .and_then(|n| n.trim().parse().ok())
        .expect("a vertex count");
    let stride = 3 * 8 + 3 * 4 + 3;
    assert_eq!(bytes.len() - body, n * stride, "{} vertices", n);
    bytes[body..]
        .chunks(stride)
        .map(|v| {
            let f = |i: usize| f64::from_le_bytes(v[8 * i..8 * i + 8].try_into().unwrap());
            ([f(0), f(1), f(2)], [v[36], v[37], v[38]])
        })
        .collect()
}

/// The newest `--state` once `ready` holds for it.
fn wait_state(
    path: &Path,
    child: &mut Child,
    what: &str,
    ready: impl Fn(&serde_json::Value) -> bool,
) -> serde_json::Value {
    let t0 = Instant::now();
    loop {
        assert!(
            child.try_wait().unwrap().is_none(),
            "workstation view exited while waiting for {what}"
        );
        if let Some(s) = state(path)
            && ready(&s)
        {
            return s;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(90),
            "waited 90 s for {what}; the state: {:?}",
            state(path)
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

fn xy(v: &serde_json::Value) -> Option<(f64, f64)> {
    let a = v.as_array()?;
    Some((a.first()?.as_f64()?, a.get(1)?.as_f64()?))
}

fn xyz(v: &serde_json::Value) -> Option<[f64; 3]> {
    let a = v.as_array()?;
    Some([
        a.first()?.as_f64()?,
        a.get(1)?.as_f64()?,
        a.get(2)?.as_f64()?,
    ])
}

/// Drag with the left button from `from` to `to` in 5-pixel steps, holding `hold` at the end.
fn drag(x: &Xvfb, from: (f64, f64), to: (f64, f64), hold: Duration) {
    let at = |p: (f64, f64)| [format!("{:.0}", p.0), format!("{:.0}", p.1)];
    let [fx, fy] = at(from);
    x.xdotool(&["mousemove", &fx, &fy]);
    std::thread::sleep(Duration::from_millis(700));
    x.xdotool(&["mousedown", "1"]);
    std::thread::sleep(Duration::from_millis(500));
    let steps = ((to.0 - from.0).hypot(to.1 - from.1) / 5.0).ceil().max(1.0) as usize;
    for k in 1..=steps {
        let t = k as f64 / steps as f64;
        let [px, py] = at((from.0 + t * (to.0 - from.0), from.1 + t * (to.1 - from.1)));
        x.xdotool(&["mousemove", &px, &py]);
        std::thread::sleep(Duration::from_millis(120));
    }
    std::thread::sleep(hold);
    x.xdotool(&["mouseup", "1"]);
    std::thread::sleep(Duration::from_millis(800));
}

fn focus(x: &Xvfb) {
    x.xdotool(&[
        "search",
        "--name",
        "workstation view",
        "windowfocus",
        "--sync",
    ]);
}

/// Ctrl+Q in the focused view window, and its clean exit within 30 s.
fn quit(x: &Xvfb, child: &mut Child, dir: &Path) {
    focus(x);
    x.xdotool(&["key", "ctrl+q"]);
    wait_exit(child, dir, Duration::from_secs(30));
}

fn tool(name: &'static str) -> impl Fn(&serde_json::Value) -> bool {
    move |s: &serde_json::Value| s.get("tool").and_then(|t| t.as_str()) == Some(name)
}

/// The window's state once it has drawn a few frames and knows where the region and the
/// object are on screen.
fn wait_drawn(state_file: &Path, child: &mut Child) -> serde_json::Value {
    wait_state(state_file, child, "the window", |s| {
        s.get("frames").and_then(|f| f.as_f64()).unwrap_or(0.0) >= 3.0
            && s.get("region_centre").and_then(xy).is_some()
            && s.get("object_centre").and_then(xy).is_some()
    })
}

/// Select the rope, grab the surface under `at` (it must be the 5 cm ball centred at the
/// origin), drag 80 pixels up and let go. Returns where it grabbed.
fn rope_pull_on_the_ball(
    x: &Xvfb,
    state_file: &Path,
    child: &mut Child,
    at: (f64, f64),
) -> [f64; 3] {
    focus(x);
    x.xdotool(&["key", "2"]);
    wait_state(state_file, child, "the rope selected", tool("rope"));
    x.xdotool(&[
        "mousemove",
        &format!("{:.0}", at.0),
        &format!("{:.0}", at.1),
    ]);
    let s = wait_state(state_file, child, "the surface under the mouse", |s| {
        s.pointer("/mouse/pointer")
            .and_then(xy)
            .is_some_and(|p| (p.0 - at.0).abs() < 1.5 && (p.1 - at.1).abs() < 1.5)
            && s.pointer("/mouse/hit").and_then(xyz).is_some()
    });
    let grab = s.pointer("/mouse/hit").and_then(xyz).unwrap();
    let r = grab.iter().map(|v| v * v).sum::<f64>().sqrt();
    assert!(
        (r - 0.05).abs() < 1e-3,
        "the cursor lies on the 5 cm ball: |hit| = {r}"
    );
    drag(x, at, (at.0, at.1 - 80.0), Duration::from_millis(1500));
    grab
}

/// Export (Ctrl+E) into `out`; the export's directory once its last file is written.
fn export(x: &Xvfb, out: &Path, state_file: &Path) -> std::path::PathBuf {
    focus(x);
    x.xdotool(&["key", "ctrl+e"]);
    let t0 = Instant::now();
    loop {
        let found = std::fs::read_dir(out).ok().and_then(|d| {
            d.filter_map(|e| e.ok().map(|e| e.path())).find(|p| {
                p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with("export_"))
                    && p.join("final_mesh.stl").exists() // written after final.ply
            })
        });
        if let Some(p) = found {
            return p;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "Ctrl+E exported nothing; the state: {:?}",
            state(state_file)
        );
        std::thread::sleep(Duration::from_millis(200));
    }
}

fn dist(p: &[f64; 3], q: &[f64; 3]) -> f64 {
    p.iter()
        .zip(q)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        .sqrt()
}

/// How far the points within 2 cm of `grab` stand out of the 5 cm ball at the origin, at most.
fn bump_at(points: &[([f64; 3], [u8; 3])], grab: &[f64; 3]) -> f64 {
    points
        .iter()
        .filter(|(p, _)| dist(p, grab) < 0.02)
        .map(|(p, _)| dist(p, &[0.0; 3]) - 0.05)
        .fold(f64::NEG_INFINITY, f64::max)
}

#[test]
fn the_mouse_raises_a_rope_bump_and_paints_a_stroke_that_the_export_keeps() {
    let _slot = e2e_tests::busy_slot();
    let x = Xvfb::start();
    let dir = tempfile::tempdir().unwrap();
    let state_file = dir.path().join("state.json");
    let mut child = view(
        &x,
        dir.path(),
        &[
            "--frames",
            "1000000",
            "--state",
            state_file.to_str().unwrap(),
        ],
    );
    let s = wait_drawn(&state_file, &mut child);
    let region = s.get("region_centre").and_then(xy).unwrap();
    let object = s.get("object_centre").and_then(xy).unwrap();

    // The rope: grab the surface under the region's centre, drag 80 pixels up, let go.
    let grab = rope_pull_on_the_ball(&x, &state_file, &mut child, region);

    // Paint: a stroke across the ball's front.
    focus(&x);
    x.xdotool(&["key", "4"]);
    wait_state(&state_file, &mut child, "the brush selected", tool("paint"));
    drag(
        &x,
        (object.0 - 80.0, object.1 - 20.0),
        (object.0 + 100.0, object.1 - 20.0),
        Duration::from_millis(300),
    );

    // Export (Ctrl+E) and read the points back.
    let export = export(&x, &dir.path().join("out"), &state_file);
    let points = ply_points(&export.join("final.ply"));
    // The unsculpted ball is a 5 cm sphere at the origin: the bump is the largest outward
    // displacement of the points within 2 cm of the grabbed point. (Away from the bump and
    // the knob at (−5.5, 0, 0) cm the ball stays a 5 cm sphere: printed for comparison.)
    let bump = bump_at(&points, &grab);
    let elsewhere = points
        .iter()
        .filter(|(p, _)| dist(p, &grab) > 0.04 && dist(p, &[-0.055, 0.0, 0.0]) > 0.025)
        .map(|(p, _)| (dist(p, &[0.0; 3]) - 0.05).abs())
        .fold(0.0, f64::max);
    let painted = points
        .iter()
        .filter(|(_, [r, g, b])| *r > g.saturating_add(60) && *r > b.saturating_add(60))
        .count();
    println!(
        "mouse rope bump {:.2} mm at {grab:?} (elsewhere the ball is within {:.2} mm of 5 cm); {painted} points painted of {}",
        bump * 1e3,
        elsewhere * 1e3,
        points.len()
    );
    assert!(
        bump >= 3e-3,
        "the rope drag raised the surface by {:.2} mm",
        bump * 1e3
    );
    assert!(painted >= 50, "the stroke painted {painted} points");
    quit(&x, &mut child, dir.path());
}

#[test]
fn a_model_file_opens_scaled_into_the_scene_and_the_mouse_sculpts_it() {
    // A user's scan: a sphere 60 mm across in millimetres, far from the origin, as a point
    // file. `workstation view FILE` opens it 10 cm across at the origin: the 5 cm ball the
    // demo's tools are sized for.
    let _slot = e2e_tests::busy_slot();
    let x = Xvfb::start();
    let dir = tempfile::tempdir().unwrap();
    let mut scan = sim_core::sampling::Shape::Sphere { radius: 30.0 }.sample(3000, 5);
    scan.positions
        .iter_mut()
        .for_each(|p| *p += glam::DVec3::new(100.0, -40.0, 250.0));
    let model = dir.path().join("my scan.ply");
    let file = std::fs::File::create(&model).unwrap();
    sim_core::io::write_points_ply(std::io::BufWriter::new(file), &scan, false).unwrap();
    let state_file = dir.path().join("state.json");
    let mut child = view(
        &x,
        dir.path(),
        &[
            model.to_str().unwrap(),
            "--frames",
            "1000000",
            "--state",
            state_file.to_str().unwrap(),
        ],
    );
    let s = wait_drawn(&state_file, &mut child);
    assert_eq!(s.get("points").and_then(|p| p.as_f64()), Some(3000.0));
    let region = s.get("region_centre").and_then(xy).unwrap();
    let grab = rope_pull_on_the_ball(&x, &state_file, &mut child, region);
    let export = export(&x, &dir.path().join("out"), &state_file);
    let bump = bump_at(&ply_points(&export.join("final.ply")), &grab);
    println!("mouse rope bump on a model file: {:.2} mm", bump * 1e3);
    assert!(
        bump >= 3e-3,
        "the rope drag raised the surface by {:.2} mm",
        bump * 1e3
    );
    quit(&x, &mut child, dir.path());
}

#[test]
fn view_share_draws_another_stations_cursor_where_it_is() {
    let _slot = e2e_tests::busy_slot();
    let x = Xvfb::start();
    let dir = tempfile::tempdir().unwrap();
    let port = e2e_tests::free_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let router_log = std::fs::File::create(dir.path().join("router.log")).unwrap();
    let _router = e2e_tests::ChildGuard(Some(
        Command::new(binary("workstation"))
            .args(["share-router", "--listen", &endpoint])
            .stdout(router_log.try_clone().unwrap())
            .stderr(router_log)
            .spawn()
            .unwrap(),
    ));
    // Another station, `far`, as the bus sees it: its telemetry with its cursor on the ball's
    // top, 50 times a second.
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let publisher = {
        let (stop, endpoint) = (stop.clone(), endpoint.clone());
        std::thread::spawn(move || {
            let rt = tokio::runtime::Builder::new_multi_thread()
                .worker_threads(1)
                .enable_all()
                .build()
                .unwrap();
            rt.block_on(async {
                let config = workstation::share::bus::client_config(&endpoint, None).unwrap();
                let session = zenoh::open(config).await.unwrap();
                let key = workstation::share::Keys::new("demo").telemetry("far");
                let mut t = workstation::share::Telemetry {
                    station: "far".into(),
                    t_ns: 0,
                    cursor: Some([0.0, 0.052, 0.0]),
                    force: [0.0; 3],
                    buttons: 0,
                    tool: Some("touch".into()),
                    force_loop_hz: 1000.0,
                    sim_hz: 1000.0,
                    rtt_us: 0.0,
                    version: 0,
                };
                while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                    t.t_ns += 20_000_000;
                    session
                        .put(&key, serde_json::to_vec(&t).unwrap())
                        .await
                        .unwrap();
                    tokio::time::sleep(Duration::from_millis(20)).await;
                }
                session.close().await.unwrap();
            });
        })
    };
    let shot = dir.path().join("window.png");
    let state_file = dir.path().join("state.json");
    let mut child = view(
        &x,
        dir.path(),
        &[
            "--share",
            &endpoint,
            "--station",
            "c",
            "--screenshot",
            shot.to_str().unwrap(),
            "--frames",
            "60",
            "--state",
            state_file.to_str().unwrap(),
        ],
    );
    wait_exit(&mut child, dir.path(), Duration::from_secs(120));
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    publisher.join().unwrap();
    let s = state(&state_file).expect("the state file");
    let others = s["others"].as_array().expect("others").clone();
    assert_eq!(others.len(), 1, "{s}");
    assert_eq!(others[0][0].as_str(), Some("far"));
    let (cx, cy) = xy(&others[0][1]).expect("far's cursor is in view");
    // Its ring (orange) is drawn there, and nowhere else is orange.
    let pic = Picture::load(&shot);
    let orange = |[r, g, b]: [u8; 3]| r > 220 && (130..210).contains(&g) && b < 90;
    let (x0, y0) = (
        (cx as usize).saturating_sub(12),
        (cy as usize).saturating_sub(12),
    );
    let near = pic.fraction((x0, x0 + 24), (y0, y0 + 24), orange);
    let everywhere = pic.fraction((0, pic.width), (0, pic.height), orange);
    assert!(
        near > 0.08,
        "far's cursor ring covers {near:.3} around ({cx}, {cy})"
    );
    assert!(
        everywhere * (pic.width * pic.height) as f64 <= 2500.0,
        "orange elsewhere: {everywhere:.4} of the window"
    );
}
