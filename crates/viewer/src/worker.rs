//! The background worker: everything that evaluates the BRDF in bulk runs here, off the UI
//! thread — the f_r map of the disk view, the lobe mesh, the quadtree build, the expected
//! cell masses (the independent integrator of `brdf_validate`) and the samples.
//!
//! The UI sends a [`Request`] whenever an input changes; each carries a generation number.
//! The worker always works on the newest request: it drops queued stale ones, and between
//! steps (and between sample chunks) it checks the shared latest generation and abandons a
//! stale job. Results come back as [`Update`]s tagged with their generation, so the UI can
//! ignore anything stale that was already in flight.

use crate::grids::{FrMap, LobeGrid, TreeView, fr_map, lobe_grid};
use brdf_core::Brdf;
use brdf_validate::{CellGrid, Validation};
use glam::{Vec2, Vec3};
use quadtree_sampler::{
    AnySampler, BakeConfig, BakedSampler, BuildConfig, DEFAULT_BAKE_NODE_BUDGET, DirectionSampler,
    MixtureTree, QuadtreeSampler, Role, SamplerMode, TreeStats,
};
use rand_core::SeedableRng;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};
use std::time::Instant;

/// Samples drawn between two progress updates (and cancellation checks).
pub const CHUNK: u64 = 1 << 14;

/// At most this many sample points are kept for the point cloud (the histogram counts all).
pub const MAX_POINTS: usize = 4_000;

/// Which sampler the laboratory draws from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SamplerKind {
    /// The seed's method: descend the tree by v1, rejection-sample in the leaf.
    Rejection,
    /// The tree with a bilinear warp inside each leaf (no rejection; pdf not ∝ f·cos).
    Warp,
    /// Cosine-weighted hemisphere sampling (a baseline).
    Cosine,
    /// Uniform hemisphere sampling (a baseline).
    Uniform,
    /// The model's own analytic sampler (a baseline).
    Analytic,
    /// The baked sampler of SPEC §7 (rejection mode): trees at a grid of incident directions,
    /// baked once per model, parameters and build options, sampled at the current wi (off
    /// its grid as the user drags) through the exact mixture of its rotated neighbours (one
    /// tree, as it is, for a model that does not depend on wi).
    Baked,
}

impl SamplerKind {
    /// Every kind, in the order the UI lists them.
    pub const ALL: [Self; 6] = [
        Self::Rejection,
        Self::Warp,
        Self::Cosine,
        Self::Uniform,
        Self::Analytic,
        Self::Baked,
    ];

    /// The name the `brdf` CLI uses for this mode.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Rejection => "rejection",
            Self::Warp => "warp",
            Self::Cosine => "cosine",
            Self::Uniform => "uniform",
            Self::Analytic => "analytic",
            Self::Baked => "baked",
        }
    }
}

/// One unit of work: the state of every input that affects a result.
#[derive(Clone, Debug)]
pub struct Request {
    /// Generation number (strictly increasing per worker).
    pub generation: u64,
    /// The model, built from the current parameters.
    pub brdf: Arc<dyn Brdf>,
    /// Incident direction, local frame, unit, above the horizon.
    pub wi: Vec3,
    /// How to build the tree.
    pub config: BuildConfig,
    /// The sampler to draw from.
    pub sampler: SamplerKind,
    /// Samples to draw in all.
    pub samples: u64,
    /// The histogram cells.
    pub grid: CellGrid,
    /// Seed of the sample stream.
    pub seed: u64,
    /// Side of the f_r map, in pixels.
    pub map_res: usize,
    /// Lobe mesh resolution: rings in θ (sectors in φ are twice this).
    pub lobe_res: usize,
}

/// The sample tallies so far.
#[derive(Clone, Debug, Default)]
pub struct SampleState {
    /// Samples drawn so far (including lost ones).
    pub drawn: u64,
    /// Samples asked for.
    pub target: u64,
    /// Per-cell counts (row-major, as [`CellGrid::dims`]).
    pub counts: Vec<u64>,
    /// Sample points on the tree's square (at most [`MAX_POINTS`]).
    pub points: Vec<Vec2>,
    /// Samples the sampler gave no direction for.
    pub lost: u64,
    /// Rejection trials in all.
    pub trials: u64,
    /// Seconds spent sampling.
    pub seconds: f64,
    /// Times f_r exceeded a leaf's bound during sampling (the tree's counter).
    pub bound_violations: u64,
    /// The baked sampler's grid trees answering at wi and their weights (empty for the
    /// other samplers): one tree where the bake found its neighbours agree.
    pub mixture: Vec<MixtureTree>,
}

/// What the worker reports. Every variant carries the request's generation.
#[derive(Clone, Debug)]
pub enum Update {
    /// The f_r map is ready.
    Map(u64, Arc<FrMap>),
    /// The lobe grid is ready.
    Lobe(u64, Arc<LobeGrid>),
    /// The tree is built.
    Tree {
        /// Generation.
        generation: u64,
        /// The tree, as the views inspect it.
        tree: Arc<TreeView>,
        /// Its statistics.
        stats: TreeStats,
        /// Seconds the build took.
        seconds: f64,
        /// The directional albedo the tree's volume gives.
        albedo: f64,
    },
    /// The expected cell masses ∫ Y(f_r) dA are integrated.
    Expected(u64, Arc<Vec<f64>>),
    /// Each cell's probability under the sampler's own reported pdf (∫ pdf dω; their sum is at
    /// most 1, the rest being the samples it gives no direction for). Sent for every sampler
    /// but the tree's own rejection sampler, whose pdf is f·cos over the tree's volume.
    ExpectedOwn(u64, Arc<Vec<f64>>),
    /// More samples were drawn (cumulative).
    Samples(u64, Arc<SampleState>),
    /// The job is complete.
    Done(u64),
    /// The job failed; the message says why.
    Failed(u64, String),
}

impl Update {
    /// The generation this update belongs to.
    #[must_use]
    pub fn generation(&self) -> u64 {
        match self {
            Self::Map(g, _)
            | Self::Lobe(g, _)
            | Self::Expected(g, _)
            | Self::ExpectedOwn(g, _)
            | Self::Samples(g, _)
            | Self::Done(g)
            | Self::Failed(g, _) => *g,
            Self::Tree { generation, .. } => *generation,
        }
    }
}

/// A handle on the worker thread. Dropping it stops the thread.
pub struct Worker {
    requests: Option<Sender<Request>>,
    updates: Receiver<Update>,
    latest: Arc<AtomicU64>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Worker {
    /// Starts the worker; `wake` is called after every update is sent (the UI passes
    /// `egui::Context::request_repaint`).
    #[must_use]
    pub fn spawn(wake: impl Fn() + Send + 'static) -> Self {
        let (req_tx, req_rx) = channel::<Request>();
        let (up_tx, up_rx) = channel::<Update>();
        let latest = Arc::new(AtomicU64::new(0));
        let shared = Arc::clone(&latest);
        let thread = std::thread::Builder::new()
            .name("brdf-viewer-worker".into())
            .spawn(move || run(&req_rx, &up_tx, &shared, &wake))
            .expect("spawning the viewer's worker thread");
        Self {
            requests: Some(req_tx),
            updates: up_rx,
            latest,
            thread: Some(thread),
        }
    }

    /// Queues `request`; any older job is abandoned at its next check.
    pub fn submit(&self, request: Request) {
        self.latest.store(request.generation, Ordering::SeqCst);
        if let Some(tx) = &self.requests {
            // The thread only ends when this handle drops, so sending cannot fail here.
            let _ = tx.send(request);
        }
    }

    /// Every update that arrived since the last call.
    pub fn poll(&self) -> Vec<Update> {
        self.updates.try_iter().collect()
    }
}

impl Drop for Worker {
    /// Tells the thread to stop (it checks between stages) and waits for it briefly; a thread
    /// still inside one long build is left to finish on its own, so that dropping the viewer
    /// (a `--timeout` that expired, a closed window) never waits on a build.
    fn drop(&mut self) {
        self.latest.store(u64::MAX, Ordering::SeqCst);
        self.requests = None;
        if let Some(t) = self.thread.take() {
            let start = std::time::Instant::now();
            while !t.is_finished() && start.elapsed() < std::time::Duration::from_millis(200) {
                std::thread::sleep(std::time::Duration::from_millis(2));
            }
            if t.is_finished() {
                let _ = t.join();
            }
        }
    }
}

fn run(
    requests: &Receiver<Request>,
    updates: &Sender<Update>,
    latest: &AtomicU64,
    wake: &(impl Fn() + Send),
) {
    let Ok(mut next) = requests.recv() else {
        return;
    };
    loop {
        // Skip to the newest queued request.
        loop {
            match requests.try_recv() {
                Ok(r) => next = r,
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => return,
            }
        }
        let generation = next.generation;
        let live = || latest.load(Ordering::SeqCst) == generation;
        let send = |u: Update| {
            let _ = updates.send(u);
            wake();
        };
        process(&next, &live, &send);
        match requests.recv() {
            Ok(r) => next = r,
            Err(_) => return,
        }
    }
}

/// Runs one request to completion (or until `live` turns false), sending updates.
pub fn process(req: &Request, live: &dyn Fn() -> bool, send: &dyn Fn(Update)) {
    let g = req.generation;
    let brdf: &dyn Brdf = &*req.brdf;
    send(Update::Map(
        g,
        Arc::new(fr_map(brdf, req.wi, req.config.map, req.map_res)),
    ));
    if !live() {
        return;
    }
    send(Update::Lobe(
        g,
        Arc::new(lobe_grid(brdf, req.wi, req.lobe_res)),
    ));
    if !live() {
        return;
    }
    if brdf.is_delta() {
        send(Update::Failed(
            g,
            format!(
                "`{}` is a Dirac delta: it has no continuous part to build a tree for or to sample \
                 (its only direction is the mirror of wi, marked on the disk)",
                brdf.name()
            ),
        ));
        return;
    }
    let t0 = Instant::now();
    // The tree is built (and shown) whichever sampler draws: it is what the lab is about.
    // (The warp below builds its own tree, always over the concentric map.)
    let tree_sampler = match QuadtreeSampler::new(brdf, req.wi, req.config) {
        Ok(s) => s,
        Err(e) => {
            send(Update::Failed(g, e.to_string()));
            return;
        }
    };
    send(Update::Tree {
        generation: g,
        tree: Arc::new(TreeView::new(tree_sampler.tree().clone())),
        stats: tree_sampler.stats(),
        seconds: t0.elapsed().as_secs_f64(),
        albedo: tree_sampler.albedo(),
    });
    if !live() {
        return;
    }
    let validation = match Validation::new(brdf, req.wi, req.grid, 1e-7) {
        Ok(v) => v,
        Err(e) => {
            send(Update::Failed(g, e.to_string()));
            return;
        }
    };
    send(Update::Expected(g, Arc::new(validation.mass().to_vec())));
    if !live() {
        return;
    }
    let baked = if req.sampler == SamplerKind::Baked {
        match baked_for(req) {
            Ok(b) => Some(b),
            Err(e) => {
                send(Update::Failed(g, e));
                return;
            }
        }
    } else {
        None
    };
    if !live() {
        return;
    }
    let mode = match req.sampler {
        SamplerKind::Rejection | SamplerKind::Baked => None,
        SamplerKind::Warp => Some(SamplerMode::Warp),
        SamplerKind::Cosine => Some(SamplerMode::Cosine),
        SamplerKind::Uniform => Some(SamplerMode::Uniform),
        SamplerKind::Analytic => Some(SamplerMode::Analytic),
    };
    let mixture = baked
        .as_ref()
        .and_then(|b| b.mixture_at(Role::Importance, req.wi).ok())
        .unwrap_or_default();
    let other = match (baked, mode) {
        (Some(b), _) => AnySampler::baked(b, req.wi).map(Some),
        (None, Some(mode)) => AnySampler::new(brdf, req.wi, mode, req.config).map(Some),
        (None, None) => Ok(None),
    };
    let other = match other {
        Ok(o) => o,
        Err(e) => {
            send(Update::Failed(g, e.to_string()));
            return;
        }
    };
    let sampler: &dyn DirectionSampler = match &other {
        Some(b) => b,
        None => &tree_sampler,
    };
    // The second χ²'s cells: the sampler's own pdf integrated like the masses, cut where the
    // sampler says its density may be concentrated (a baked sampler's rotated neighbour
    // lobes); the tree's rejection sampler is f·cos over its volume: the first χ² judges
    // that shape already.
    if req.sampler != SamplerKind::Rejection {
        let own = validation.own_probability_with(
            &|w: Vec3| f64::from(sampler.pdf(w)),
            &sampler.density_hints(),
        );
        send(Update::ExpectedOwn(g, Arc::new(own)));
        if !live() {
            return;
        }
    }
    let map = req.config.map;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(req.seed);
    let mut state = SampleState {
        target: req.samples,
        counts: vec![0; req.grid.len()],
        mixture,
        ..SampleState::default()
    };
    let t0 = Instant::now();
    while state.drawn < req.samples {
        let n = CHUNK.min(req.samples - state.drawn);
        for _ in 0..n {
            state.drawn += 1;
            match sampler.sample(&mut rng) {
                Some(s) if !s.delta => {
                    state.trials += u64::from(s.trials);
                    if let Some(c) = req.grid.cell_of(s.wo) {
                        state.counts[c] += 1;
                    }
                    if state.points.len() < MAX_POINTS {
                        state.points.push(map.direction_to_square(s.wo));
                    }
                }
                _ => state.lost += 1,
            }
        }
        state.seconds = t0.elapsed().as_secs_f64();
        if other.is_none() {
            state.bound_violations = tree_sampler.bound_violations();
        }
        send(Update::Samples(g, Arc::new(state.clone())));
        if !live() {
            return;
        }
    }
    send(Update::Done(g));
}

/// The last bake, by model, parameters and build options: a drag of wi (or of the sample
/// count, the cells, the seed) reuses it; any other change bakes again.
static BAKE: std::sync::Mutex<Option<(String, Arc<BakedSampler>)>> = std::sync::Mutex::new(None);

/// The bake for a request's model and options (from the cache when it is the last one).
fn baked_for(req: &Request) -> Result<Arc<BakedSampler>, String> {
    let key = format!(
        "{} {:?} {:?}",
        req.brdf.name(),
        req.brdf.params(),
        req.config
    );
    let mut cache = BAKE
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some((k, b)) = cache.as_ref()
        && *k == key
    {
        return Ok(b.clone());
    }
    let config = BakeConfig {
        build: BuildConfig {
            node_budget: req.config.node_budget.min(DEFAULT_BAKE_NODE_BUDGET),
            ..req.config
        },
        ..BakeConfig::default()
    };
    let b = Arc::new(BakedSampler::new(req.brdf.clone(), config).map_err(|e| e.to_string())?);
    *cache = Some((key, b.clone()));
    Ok(b)
}
