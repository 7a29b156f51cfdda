//! `workstation share-router`: an embedded Zenoh router for one site, holding each scene's
//! [`Keeper`]. Thin driver: it routes like any Zenoh router (stations connect to it; other
//! sites' `zenohd` routers link to it), takes proposals from `haptic-sculpt/*/propose/*`,
//! publishes each accepted state on `…/edits` and each answer on `…/verdicts/<station>`, answers
//! `…/state` with the current state, and says each scene's status on `…/keeper` twice a second.
//! With `--store DIR` each scene's current state is also a file (`DIR/<scene>.hss`, the wire
//! format) written before it is published, so a restarted router keeps the scenes it had.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context as _;
use zenoh::qos::CongestionControl;

use super::bus::{self, RouterTls};
use super::keeper::{Keeper, Verdict};
use super::{KeeperStatus, Keys, ROOT, VerdictMessage, wire};

/// Most scenes one router keeps (each scene name in a key makes one).
pub const MAX_SCENES: usize = 256;

/// Arguments of `workstation share-router`.
#[derive(Debug, Clone, clap::Args)]
pub struct RouterArgs {
    /// Where stations (and other sites' routers) connect: tcp/HOST:PORT for one trusted
    /// network, tls/HOST:PORT for mutual TLS (then --tls-cert, --tls-key, --authorized).
    /// Repeat to listen on several.
    #[arg(long, value_name = "ENDPOINT", default_value = "tcp/0.0.0.0:7447")]
    pub listen: Vec<String>,
    /// Other routers to link to (another site's zenohd or share-router). Repeatable.
    #[arg(long, value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// The router's certificate (PEM), which stations pin (`workstation share-identity router`).
    #[arg(long, value_name = "FILE", requires_all = ["tls_key", "authorized"])]
    pub tls_cert: Option<PathBuf>,
    /// The router certificate's private key (PEM).
    #[arg(long, value_name = "FILE", requires = "tls_cert")]
    pub tls_key: Option<PathBuf>,
    /// The stations that may join: their certificates (PEM, concatenated); each one's common
    /// name is the station's name, the only name it may edit and report under.
    #[arg(long, value_name = "FILE", requires = "tls_cert")]
    pub authorized: Option<PathBuf>,
    /// Another site's router (its certificate's common name, listed in --authorized) that
    /// relays its stations' proposals and telemetry (repeatable); see deploy/zenohd/.
    #[arg(long, value_name = "NAME", requires = "authorized")]
    pub linked_router: Vec<String>,
    /// Keep each scene's current state in DIR (read back at start).
    #[arg(long, value_name = "DIR")]
    pub store: Option<PathBuf>,
    /// Stop after this many seconds [default: at Ctrl-C].
    #[arg(long)]
    pub seconds: Option<f64>,
}

/// `workstation share-router`.
pub fn share_router_command(args: &RouterArgs) -> anyhow::Result<()> {
    if let Some(s) = args.seconds {
        anyhow::ensure!(
            s.is_finite() && s > 0.0 && s <= 1e7,
            "--seconds must be positive and at most 1e7 (got {s})"
        );
    }
    let tls = args.tls_cert.as_ref().map(|cert| RouterTls {
        cert: cert.clone(),
        key: args.tls_key.clone().expect("clap requires it"),
        authorized: args.authorized.clone().expect("clap requires it"),
        linked: args.linked_router.clone(),
    });
    let config = bus::router_config(&args.listen, &args.connect, tls.as_ref())?;
    if let Some(t) = &tls {
        let names = bus::authorized_names(&t.authorized)?;
        println!("share-router: stations allowed: {}", names.join(", "));
    }
    let stop = Arc::new(AtomicBool::new(false));
    let s = Arc::clone(&stop);
    let seconds = args.seconds;
    std::thread::spawn(move || {
        let t0 = std::time::Instant::now();
        loop {
            std::thread::sleep(Duration::from_millis(100));
            if crate::session::run::interrupted()
                || seconds.is_some_and(|s| t0.elapsed().as_secs_f64() >= s)
            {
                s.store(true, Ordering::Release);
                return;
            }
        }
    });
    crate::session::run::catch_interrupt();
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .context("starting the router's runtime")?;
    println!("share-router: listening on {}", args.listen.join(", "));
    runtime.block_on(serve(config, args.store.as_deref(), stop))
}

/// Route and keep until `stop`.
pub async fn serve(
    config: zenoh::Config,
    store: Option<&Path>,
    stop: Arc<AtomicBool>,
) -> anyhow::Result<()> {
    let mut keepers: BTreeMap<String, Keeper> = BTreeMap::new();
    if let Some(dir) = store {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for (scene, keeper) in load_store(dir)? {
            println!(
                "share-router: scene `{scene}` at version {} from {}",
                keeper.version(),
                dir.display()
            );
            keepers.insert(scene, keeper);
        }
    }
    let session = bus::open(config, "router").await?;
    let err = |e: zenoh::Error| anyhow::anyhow!("{e}");
    let proposals = session
        .declare_subscriber(format!("{ROOT}/*/propose/*"))
        .await
        .map_err(err)?;
    let states = session
        .declare_queryable(format!("{ROOT}/*/state"))
        .await
        .map_err(err)?;
    let mut tick = tokio::time::interval(Duration::from_millis(500));
    while !stop.load(Ordering::Acquire) {
        tokio::select! {
            s = proposals.recv_async() => {
                let s = s.map_err(err)?;
                let key = s.key_expr().as_str().to_owned();
                let Some((scene, station)) = scene_and_station(&key) else {
                    tracing::warn!("a proposal on `{key}`: not a scene and station name");
                    continue;
                };
                if !keepers.contains_key(scene) && keepers.len() >= MAX_SCENES {
                    tracing::warn!("a proposal for a new scene `{scene}` refused: {MAX_SCENES} scenes kept already");
                    continue;
                }
                let keeper = keepers.entry(scene.to_owned()).or_insert_with(|| Keeper::new(scene));
                let verdict = keeper.propose(station, &s.payload().to_bytes());
                let keys = Keys::new(scene);
                let message = match verdict {
                    Verdict::Accepted { id, seq, ordered } => {
                        if let Some(dir) = store {
                            save_state(dir, scene, &ordered)?;
                        }
                        session.put(keys.edits(), ordered).congestion_control(CongestionControl::Block).await.map_err(err)?;
                        tracing::info!("scene `{scene}` version {seq}: {id}");
                        VerdictMessage { id: Some(id.to_string()), station: Some(id.station), counter: Some(id.counter), accepted: true, seq: Some(seq), reason: None, message: None }
                    }
                    Verdict::Refused { id, reason, message } => {
                        tracing::warn!("scene `{scene}`: refused a proposal from `{station}` ({reason}): {message}");
                        VerdictMessage {
                            id: id.as_ref().map(ToString::to_string),
                            station: id.as_ref().map(|i| i.station.clone()),
                            counter: id.as_ref().map(|i| i.counter),
                            accepted: false,
                            seq: None,
                            reason: Some(reason.to_owned()),
                            message: Some(message),
                        }
                    }
                };
                let json = serde_json::to_vec(&message).expect("a verdict serialises");
                session.put(keys.verdicts(station), json).congestion_control(CongestionControl::Block).await.map_err(err)?;
            }
            q = states.recv_async() => {
                let q = q.map_err(err)?;
                let key = q.key_expr().as_str().to_owned();
                let scene = key.strip_prefix(&format!("{ROOT}/")).and_then(|k| k.strip_suffix("/state"));
                if let Some(snapshot) = scene.and_then(|s| keepers.get(s)).and_then(Keeper::snapshot) {
                    q.reply(key.clone(), snapshot.to_vec()).await.map_err(err)?;
                }
                // Dropping the query ends it: no state yet means no reply.
            }
            _ = tick.tick() => {
                for (scene, k) in &keepers {
                    let status = KeeperStatus {
                        scene: scene.clone(),
                        version: k.version(),
                        current: k.current().map(ToString::to_string),
                        points: k.points() as u64,
                        refusals: k.refusals().iter().map(|(r, n)| ((*r).to_owned(), *n)).collect(),
                    };
                    let json = serde_json::to_vec(&status).expect("a status serialises");
                    session.put(Keys::new(scene).keeper(), json).congestion_control(CongestionControl::Drop).await.map_err(err)?;
                }
            }
        }
    }
    session.close().await.map_err(err)?;
    Ok(())
}

/// `haptic-sculpt/<scene>/propose/<station>` → (scene, station), both valid names.
fn scene_and_station(key: &str) -> Option<(&str, &str)> {
    let rest = key.strip_prefix(ROOT)?.strip_prefix('/')?;
    let (scene, rest) = rest.split_once('/')?;
    let station = rest.strip_prefix("propose/")?;
    (wire::valid_name(scene) && wire::valid_name(station)).then_some((scene, station))
}

fn save_state(dir: &Path, scene: &str, ordered: &[u8]) -> anyhow::Result<()> {
    let path = dir.join(format!("{scene}.hss"));
    let tmp = dir.join(format!(".{scene}.hss.tmp"));
    std::fs::write(&tmp, ordered).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, &path).with_context(|| format!("writing {}", path.display()))
}

fn load_store(dir: &Path) -> anyhow::Result<Vec<(String, Keeper)>> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
        let path = e?.path();
        let Some(scene) = path
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(|n| n.strip_suffix(".hss"))
            .filter(|n| wire::valid_name(n))
        else {
            continue;
        };
        let bytes = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
        let keeper = Keeper::restore(scene, bytes)
            .map_err(|e| anyhow::anyhow!("{}: not a stored state: {e}", path.display()))?;
        out.push((scene.to_owned(), keeper));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proposal_keys_name_a_scene_and_a_station() {
        assert_eq!(
            scene_and_station("haptic-sculpt/demo/propose/a-1"),
            Some(("demo", "a-1"))
        );
        assert_eq!(scene_and_station("haptic-sculpt/demo/edits"), None);
        assert_eq!(scene_and_station("other/demo/propose/a"), None);
    }
}
