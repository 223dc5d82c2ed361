//! Cluster mode: several rigcast nodes share their subjects over NATS, so a viewer or engine
//! connected to any node sees every performer and character of the deployment.
//!
//! ```text
//!  node A                                NATS                              node B
//!  tick ─▶ frames ─▶ publish ─▶ core: {ns}.frame.{site}.{key} ──▶ relay ─▶ B's clients (bytes
//!                                                                 │       as sent by A, only
//!                                                                 │       the subject id is B's)
//!                                                                 └──▶ RemoteSource ─▶ B's
//!                                                                      performers, VMC, status
//!  subjects ─▶ entry ─▶ JetStream KV "{ns}_subjects", key {site}.{key}: skeleton + mapping
//!                       (retained and watched: B makes one subject per entry, also later;
//!                        re-put every HEARTBEAT, forgotten after ENTRY_MAX_AGE without one)
//! ```
//!
//! - **Who computes what.** A performer (mapping + retarget) runs on the node that has its
//!   source. A node that relays another's subject forwards the frames it receives as they are
//!   (same seq, same rotations, same `send_nanos`) the moment they arrive, without waiting for
//!   its own tick; it re-encodes nothing.
//! - **Loss.** A remote subject whose frames stop for `lost_after_secs` is a lost source on the
//!   relaying node (its performers ease, hold or idle as configured); when the frames come
//!   back (the node restarted) it is live again. Nothing restarts elsewhere. A node re-puts
//!   its entries every [`HEARTBEAT`] and the bucket drops an entry older than
//!   [`ENTRY_MAX_AGE`], so a node killed without deleting its entries is forgotten by the
//!   bucket, and the nodes relaying it say "its node stopped answering".
//! - **Names.** Subjects are matched across nodes by site and name, never by id (ids are per
//!   node). On a relaying node a remote subject is called `NAME@SITE`.
//! - **Discovery.** A node reads the KV bucket when it starts and watches it while it runs
//!   (`discover`): subjects published later become relayed subjects here without a restart.
//!   A performer may name a subject of another node (`NAME@SITE`) that is not published yet:
//!   the subject is made here at start, waiting (`connecting`), and drives the performer
//!   once its node publishes it.
//! - **Control.** A change to a relayed subject is carried out by its owner (`control`),
//!   with the deployment's control token checked there too.
//! - **Mappings.** The automatic mapper's tables are shared through a second bucket
//!   (`mappings`), so a pair is mapped once per deployment.

mod control;
mod discover;
mod entry;
mod mappings;
mod publish;
mod remote;

use std::time::Duration;

use anyhow::Context;
use async_nats::jetstream::{self, kv};

pub use crate::cluster_config::ClusterConfig;
pub use crate::stats::MappingShareCounts;
pub use control::{run_control_service, subject_of, Forwarder, Origin};
pub use discover::{run_discovery, Known, LiveThreads};
pub use entry::{token, SubjectEntry};
pub use mappings::SharedMappings;
pub use publish::{run_entries, run_publisher};
pub use remote::{run_relay, Change, RemoteFeeds, RemoteSource};

/// A connection to the deployment's NATS system and its subject bucket.
pub struct Cluster {
    /// The client (cheap to clone; reconnects and fails over by itself).
    pub client: async_nats::Client,
    /// The subject bucket.
    pub kv: kv::Store,
    /// The shared mapping cache's bucket.
    pub mappings: kv::Store,
    /// How often the shared mapping cache was used.
    pub mapping_counts: std::sync::Arc<MappingShareCounts>,
    /// The settings it was made with.
    pub config: ClusterConfig,
}

/// How often a node re-puts its subject entries, so the bucket (and the nodes watching it)
/// can tell a live node from one that was killed without deleting them.
pub const HEARTBEAT: Duration = Duration::from_secs(1);

/// Age at which the bucket drops an entry that was not put again, and a watching node counts
/// its node as gone: five heartbeats, so a node delayed by a loaded machine is not dropped.
pub const ENTRY_MAX_AGE: Duration = Duration::from_secs(5);

/// Largest the shared mapping cache's bucket grows (a table is a few KB); beyond it puts are
/// refused and tables are computed where needed.
const MAPPINGS_MAX_BYTES: i64 = 64 << 20;

/// A bucket keeping only each key's latest value, replicated as `config` asks.
fn latest_only(bucket: String, description: &str, config: &ClusterConfig) -> kv::Config {
    kv::Config {
        bucket,
        description: description.into(),
        history: 1,
        num_replicas: config.kv_replicas,
        ..Default::default()
    }
}

/// Opens bucket `name`, creating it with `config` when it does not exist yet. An existing
/// bucket gets `config`'s `max_age` (a bucket made by an older rigcast kept entries forever).
async fn open_bucket(
    js: &jetstream::Context,
    config: kv::Config,
    servers: &str,
) -> anyhow::Result<kv::Store> {
    if let Ok(kv) = js.get_key_value(config.bucket.clone()).await {
        set_max_age(js, &kv, config.max_age)
            .await
            .with_context(|| format!("cannot set the entry age of the KV bucket {}", kv.name))?;
        return Ok(kv);
    }
    let name = config.bucket.clone();
    js.create_key_value(config).await.with_context(|| {
        format!("cannot open the KV bucket {name} (is JetStream enabled on {servers}?)")
    })
}

/// Gives bucket `kv`'s stream `max_age` (zero: kept forever) when it has another one.
async fn set_max_age(
    js: &jetstream::Context,
    kv: &kv::Store,
    max_age: Duration,
) -> anyhow::Result<()> {
    let mut stream = js.get_stream(&kv.stream_name).await?;
    let mut config = stream.info().await?.config.clone();
    if config.max_age == max_age {
        return Ok(());
    }
    config.max_age = max_age;
    // NATS refuses a duplicate window longer than the age (it shortens it itself only when
    // the stream is made).
    if !max_age.is_zero() && config.duplicate_window > max_age {
        config.duplicate_window = max_age;
    }
    js.update_stream(&config).await?;
    Ok(())
}

/// How long connecting to NATS may take at start-up before the server gives up.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(5);

impl Cluster {
    /// Connects to the first reachable server of `config` and opens (or creates) the bucket.
    pub async fn connect(config: &ClusterConfig) -> anyhow::Result<Cluster> {
        config.validate()?;
        let mut opts = async_nats::ConnectOptions::new()
            .name(format!("rigcast {}", config.site))
            .connection_timeout(CONNECT_TIMEOUT)
            .max_reconnects(None::<usize>);
        if let (Some(u), Some(p)) = (&config.user, &config.password) {
            opts = opts.user_and_password(u.clone(), p.clone());
        }
        if let Some(seed) = &config.nkey_seed {
            opts = opts.nkey(seed.clone());
        }
        let servers = config.servers.join(", ");
        let client =
            tokio::time::timeout(CONNECT_TIMEOUT * 2, opts.connect(config.servers.as_slice()))
                .await
                .map_err(|_| anyhow::anyhow!("no answer within {:?}", CONNECT_TIMEOUT * 2))
                .and_then(|r| r.map_err(anyhow::Error::from))
                .with_context(|| format!("cannot connect to NATS at {servers}"))?;
        let js = jetstream::new(client.clone());
        let subjects = kv::Config {
            max_age: ENTRY_MAX_AGE,
            ..latest_only(
                config.bucket(),
                "rigcast subjects: skeleton and mapping per site and name",
                config,
            )
        };
        let kv = open_bucket(&js, subjects, &servers).await?;
        let shared = kv::Config {
            max_bytes: MAPPINGS_MAX_BYTES,
            ..latest_only(
                config.mappings_bucket(),
                "rigcast mapping cache shared by the nodes",
                config,
            )
        };
        let mappings = open_bucket(&js, shared, &servers).await?;
        Ok(Cluster {
            client,
            kv,
            mappings,
            mapping_counts: Default::default(),
            config: config.clone(),
        })
    }

    /// Every other site's subject entries in the bucket now, with their revisions.
    pub async fn remote_entries(&self) -> anyhow::Result<Vec<(SubjectEntry, u64)>> {
        use futures_util::StreamExt;
        let mut keys = self
            .kv
            .keys()
            .await
            .context("cannot list the cluster's subjects")?;
        let mut out = Vec::new();
        while let Some(key) = keys.next().await {
            let Ok(key) = key else { continue };
            if key.starts_with(&format!("{}.", self.config.site)) {
                continue; // our own, from an earlier run
            }
            let Ok(Some(entry)) = self.kv.entry(key.clone()).await else {
                continue;
            };
            if entry.operation != kv::Operation::Put {
                continue; // deleted by its node
            }
            match SubjectEntry::parse(&entry.value) {
                Ok(e) => out.push((e, entry.revision)),
                Err(e) => warn(&format!("cluster: entry {key} skipped: {e}")),
            }
        }
        out.sort_by(|(a, _), (b, _)| (&a.site, &a.name).cmp(&(&b.site, &b.name)));
        Ok(out)
    }
}

/// One of another node's subjects, ready to become a source subject here.
pub struct RemoteSubject {
    /// `NAME@SITE`.
    pub name: String,
    /// Its source.
    pub source: RemoteSource,
    /// Its skeleton.
    pub skeleton: std::sync::Arc<rigcast_retarget::Skeleton>,
}

/// What feeds one relayed subject: its frames' NATS subject, the id it has here, its source.
pub struct Relay {
    /// Subject id on this node.
    pub id: u32,
    /// The NATS subject its frames arrive on.
    pub subject: String,
    /// Its source's queues.
    pub feeds: RemoteFeeds,
    /// Its bucket key.
    pub key: String,
    /// Where it lives (its control requests go there).
    pub origin: Origin,
    /// The bucket revision it was made from (`None`: not published yet, a performer waits
    /// for it).
    pub revision: Option<u64>,
}

/// This node's part of the cluster, between loading and spawning.
pub struct ClusterLink {
    /// The connection.
    pub cluster: std::sync::Arc<Cluster>,
    /// One per relayed subject.
    pub relays: Vec<Relay>,
}

/// Connects to the cluster of `config` and makes a subject of every other node's subject; the
/// first gets id `first_id` (the subjects follow this node's own sources). Of `wanted` (the
/// source names this node's performers give), each `NAME@SITE` of another site that is not
/// in the bucket yet becomes a subject too, waiting for its node to publish it.
pub async fn join(
    config: &ClusterConfig,
    first_id: u32,
    wanted: &[String],
) -> anyhow::Result<(ClusterLink, Vec<RemoteSubject>)> {
    let cluster = std::sync::Arc::new(Cluster::connect(config).await?);
    let mut relays = Vec::new();
    let mut subjects = Vec::new();
    let entries = cluster.remote_entries().await?;
    for (e, revision) in &entries {
        let (source, feeds) = RemoteSource::new(e, config.lost_after())
            .with_context(|| format!("cluster subject {}", e.relayed_name()))?;
        let id = first_id + relays.len() as u32;
        relays.push(relay_of(
            config,
            id,
            &e.site,
            &e.name,
            feeds,
            Some(*revision),
        ));
        subjects.push(remote_subject(e.relayed_name(), source));
    }
    let published: Vec<String> = entries.iter().map(|(e, _)| e.relayed_name()).collect();
    for (name, site) in awaited(config, wanted, &published) {
        let (source, feeds) = RemoteSource::awaiting(&site, &name, config.lost_after())
            .with_context(|| format!("cluster subject {name}@{site}"))?;
        tracing::info!("cluster: {name}@{site} is not published yet; its performers wait for it");
        let id = first_id + relays.len() as u32;
        relays.push(relay_of(config, id, &site, &name, feeds, None));
        subjects.push(remote_subject(format!("{name}@{site}"), source));
    }
    Ok((ClusterLink { cluster, relays }, subjects))
}

/// The (name, site) of each `NAME@SITE` in `wanted` of another site than this node's and not
/// in `published`, once each.
fn awaited(
    config: &ClusterConfig,
    wanted: &[String],
    published: &[String],
) -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = Vec::new();
    for w in wanted {
        let Some((name, site)) = w.rsplit_once('@') else {
            continue;
        };
        let valid_site = !site.is_empty() && token(site) == site && site != config.site;
        let pair = (name.to_string(), site.to_string());
        if valid_site && !name.is_empty() && !published.contains(w) && !out.contains(&pair) {
            out.push(pair);
        }
    }
    out
}

fn relay_of(
    config: &ClusterConfig,
    id: u32,
    site: &str,
    name: &str,
    feeds: RemoteFeeds,
    revision: Option<u64>,
) -> Relay {
    Relay {
        id,
        subject: config.frame_subject(site, &token(name)),
        feeds,
        key: format!("{site}.{}", token(name)),
        origin: Origin {
            site: site.to_string(),
            name: name.to_string(),
        },
        revision,
    }
}

fn remote_subject(name: String, source: RemoteSource) -> RemoteSubject {
    let skeleton = source.skeleton_arc();
    RemoteSubject {
        name,
        source,
        skeleton,
    }
}

impl ClusterLink {
    /// The forwarder of control requests about the relayed subjects, signing with `token`.
    pub fn forwarder(&self, token: crate::token::ControlToken) -> Forwarder {
        let c = &self.cluster;
        let f = Forwarder::new(c.client.clone(), &c.config.namespace, &c.config.site, token);
        for r in &self.relays {
            f.add(r.id, r.origin.clone());
        }
        f
    }

    /// Starts the relays, the bucket watch, the publisher and the control service, each with
    /// only its part of `state` (`Feeds`, `Discovery`, `ControlService`); they stop when
    /// `state` shuts down. Subjects found later get their source threads from `live`
    /// and their origin recorded in `forwarder`.
    pub fn spawn(
        self,
        state: &std::sync::Arc<crate::state::ServerState>,
        live: LiveThreads,
        forwarder: std::sync::Arc<Forwarder>,
    ) -> Vec<tokio::task::JoinHandle<()>> {
        let mut known = std::collections::HashMap::new();
        let mut tasks = Vec::new();
        for r in self.relays {
            let client = self.cluster.client.clone();
            let (frames, changes) = (r.feeds.frames, r.feeds.changes);
            known.insert(r.key, Known::at_start(changes, r.revision));
            tasks.push(tokio::spawn(run_relay(
                client,
                r.subject,
                r.id,
                frames,
                state.feeds(),
            )));
        }
        let c = &self.cluster;
        tasks.push(tokio::spawn(run_discovery(
            c.clone(),
            known,
            state.discovery(),
            live,
            forwarder,
        )));
        tasks.push(tokio::spawn(run_control_service(
            c.client.clone(),
            c.config.namespace.clone(),
            c.config.site.clone(),
            state.control_service(),
        )));
        tasks.push(tokio::spawn(run_entries(c.clone(), state.feeds())));
        tasks.push(tokio::spawn(run_publisher(self.cluster, state.feeds())));
        tasks
    }
}

/// Start-up warnings go through `tracing` like the server's other reports.
fn warn(text: &str) {
    tracing::warn!("{text}");
}
