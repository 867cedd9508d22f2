//! Marching cubes on worker threads, for streamed worlds whose main thread must stay within a
//! frame budget.
//!
//! A chunk's mesh reads the chunk and the neighbours its voxel block's apron reaches (the chunks
//! at offsets `{0, 1}³` in a volume of one level, all 26 around it otherwise). [`MeshWorkers::submit`]
//! puts shares of exactly those into a small snapshot volume ([`Volume::share_chunks`]: two small
//! tables, no chunk copied; the main thread's only cost) and a worker meshes the snapshot, so the
//! main thread never waits for a mesh and the world may change meanwhile: a result is kept only
//! if no newer request for its chunk was made.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use strata_volume::{ChunkKey, KeyHasher, Volume, VoxelBlock};

use crate::{Mesh, mesh_block};

struct Job {
    key: ChunkKey,
    ticket: u64,
    snapshot: Volume,
}

/// Meshes chunks on worker threads (see the module docs).
pub struct MeshWorkers {
    jobs: Option<Sender<Job>>,
    /// (In a mutex only so that the struct is `Sync`, as an editor holding it is shared by
    /// reference; it is reached through `&mut self` by `get_mut`, never locked.)
    done: std::sync::Mutex<Receiver<(ChunkKey, u64, Mesh)>>,
    latest: HashMap<ChunkKey, u64, BuildHasherDefault<KeyHasher>>,
    /// The same requests, for the workers: a job whose request was superseded or cancelled
    /// before a worker took it is skipped, not meshed (a fast flight or a long stroke queues
    /// many requests for one chunk).
    wanted: Arc<Mutex<HashMap<ChunkKey, u64, BuildHasherDefault<KeyHasher>>>>,
    next: u64,
    workers: Vec<JoinHandle<()>>,
    /// Set when dropped: the workers stop without meshing what is still queued.
    stop: Arc<AtomicBool>,
}

impl std::fmt::Debug for MeshWorkers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshWorkers")
            .field("pending", &self.latest.len())
            .field("threads", &self.workers.len())
            .finish()
    }
}

/// Lowers the calling worker thread's scheduling priority below the normal one, so that a
/// frame's thread rarely waits for its time slices, but above the terrain's generating workers
/// (which take the least): a chunk already loaded is drawn before more are loaded, and on a
/// machine whose every core generates, meshing still keeps up (ARCHITECTURE: "Worker threads").
/// A refusal only leaves the normal priority.
fn background_priority() {
    // 24 of the portable 0–99 range is nice 9 on Linux (thread-priority maps it onto nice 19
    // down to −20 in 39 steps). Linux weighs nice 0, 9 and 19 as 1024, 137 and 15: a mesher
    // gets 9× a generator's share of a core they contend for, and an eighth of a normal thread's.
    let priority = thread_priority::ThreadPriorityValue::try_from(24u8)
        .map_or(thread_priority::ThreadPriority::Min, thread_priority::ThreadPriority::Crossplatform);
    let _ = thread_priority::set_current_thread_priority(priority);
}

impl MeshWorkers {
    /// `threads` workers (at least one).
    pub fn new(threads: usize) -> Self {
        let (tx, rx) = channel::<Job>();
        let rx = Arc::new(Mutex::new(rx));
        let (done_tx, done) = channel();
        let stop = Arc::new(AtomicBool::new(false));
        let wanted: Arc<Mutex<HashMap<ChunkKey, u64, BuildHasherDefault<KeyHasher>>>> = Arc::default();
        let workers = (0..threads.max(1))
            .map(|i| {
                let (rx, done_tx, stop, wanted) = (rx.clone(), done_tx.clone(), stop.clone(), wanted.clone());
                std::thread::Builder::new()
                    .name(format!("mesher-{i}"))
                    .spawn(move || {
                        background_priority();
                        let mut block = VoxelBlock::default();
                        loop {
                            let job = match rx.lock() {
                                Ok(r) => r.recv(),
                                Err(_) => return,
                            };
                            let Ok(job) = job else { return };
                            if stop.load(Ordering::Relaxed) {
                                return;
                            }
                            let current = wanted.lock().map(|w| w.get(&job.key) == Some(&job.ticket)).unwrap_or(true);
                            if !current {
                                continue;
                            }
                            job.snapshot.extract_block_into(job.key, &mut block);
                            let mut mesh = Mesh::default();
                            mesh_block(&block, &mut mesh);
                            if done_tx.send((job.key, job.ticket, mesh)).is_err() {
                                return;
                            }
                        }
                    })
                    .expect("a mesher thread starts")
            })
            .collect();
        MeshWorkers {
            jobs: Some(tx),
            done: std::sync::Mutex::new(done),
            latest: HashMap::default(),
            wanted,
            next: 0,
            workers,
            stop,
        }
    }

    /// The chunks the mesh of `key` reads in `volume`.
    pub fn reads(volume: &Volume, key: ChunkKey) -> impl Iterator<Item = ChunkKey> {
        // The 27 around `key`, or the 8 at offsets {0, 1}³ among them.
        let single = volume.single_level();
        key.around().filter(move |k| !single || (k.0 - key.0).min_element() >= 0)
    }

    /// The chunks whose meshes read chunk `key` (the inverse of [`MeshWorkers::reads`]): what
    /// to remesh when `key` changes.
    pub fn readers(volume: &Volume, key: ChunkKey) -> Vec<ChunkKey> {
        if volume.single_level() { crate::MeshCache::dependents(&[key]) } else { key.around().collect() }
    }

    /// Asks for a new mesh of `key` as `volume` is now (replacing any request not yet done).
    pub fn submit(&mut self, volume: &Volume, key: ChunkKey) {
        // Shares of the chunks read (see `Volume::share_chunks`): the frame's thread allocates
        // the snapshot's two small tables and copies no chunk.
        let snapshot = volume.share_chunks(Self::reads(volume, key));
        self.next += 1;
        self.latest.insert(key, self.next);
        if let Ok(mut w) = self.wanted.lock() {
            w.insert(key, self.next);
        }
        if let Some(tx) = &self.jobs {
            let _ = tx.send(Job { key, ticket: self.next, snapshot });
        }
    }

    /// Forgets a request (its chunk left memory): its result will be dropped.
    pub fn cancel(&mut self, key: ChunkKey) {
        // (Only a request made is in `wanted`: most chunks cancelled, beside those that left
        // memory, were never asked for.)
        if self.latest.remove(&key).is_some()
            && let Ok(mut w) = self.wanted.lock()
        {
            w.remove(&key);
        }
    }

    /// Meshes finished since the last call, of the latest request for their chunk.
    pub fn finished(&mut self) -> Vec<(ChunkKey, Mesh)> {
        let mut out = Vec::new();
        let done = self.done.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner);
        while let Ok((key, ticket, mesh)) = done.try_recv() {
            if self.latest.get(&key) == Some(&ticket) {
                self.latest.remove(&key);
                if let Ok(mut w) = self.wanted.lock()
                    && w.get(&key) == Some(&ticket)
                {
                    w.remove(&key);
                }
                out.push((key, mesh));
            }
        }
        out
    }

    /// Requests not finished yet.
    pub fn pending(&self) -> usize {
        self.latest.len()
    }
}

impl Drop for MeshWorkers {
    fn drop(&mut self) {
        // Nothing queued is wanted any more: each worker ends at its next job, and closing the
        // channel ends the idle ones.
        self.stop.store(true, Ordering::Relaxed);
        self.jobs = None;
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use strata_volume::brush::Sphere;

    fn mesh_of(v: &Volume, k: ChunkKey) -> Mesh {
        let (mut b, mut m) = (VoxelBlock::default(), Mesh::default());
        v.extract_block_into(k, &mut b);
        mesh_block(&b, &mut m);
        m
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn mesher_threads_run_below_the_normal_priority_and_above_the_generators() {
        let workers = MeshWorkers::new(2);
        // The threads lower themselves as they start, not to the least (19), which generation has
        // (in a process already at nice 9 or more, without the privilege to rise, they keep its
        // value).
        let base = strata_tests::process_nice().unwrap_or(0);
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
        loop {
            let nice = strata_tests::thread_nice("mesher-");
            let placed = |n: i32| (n > 0 && n < 19) || (base >= 9 && n == base);
            if nice.len() >= 2 && nice.iter().all(|&n| placed(n)) {
                break;
            }
            assert!(std::time::Instant::now() < deadline, "mesher threads' nice values: {nice:?}");
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        drop(workers);
    }

    #[test]
    fn worker_meshes_equal_direct_meshing_and_stale_requests_are_dropped() {
        let mut v = Volume::new();
        v.add(&Sphere::new(DVec3::new(20.0, 18.0, 15.0), 11.0).unwrap()).unwrap();
        let before = v.clone();
        let keys = crate::surface_chunks(&v);
        let mut workers = MeshWorkers::new(2);
        for &k in &keys {
            workers.submit(&v, k);
        }
        // A second request for the first chunk after an edit: only its result counts.
        v.subtract(&Sphere::new(DVec3::new(20.0, 18.0, 4.0), 5.0).unwrap()).unwrap();
        workers.submit(&v, keys[0]);
        let mut got = HashMap::new();
        let start = std::time::Instant::now();
        while workers.pending() > 0 && start.elapsed() < std::time::Duration::from_secs(60) {
            got.extend(workers.finished());
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        assert_eq!(workers.pending(), 0);
        assert_eq!(got.len(), keys.len());
        for &k in &keys {
            let want = if k == keys[0] { mesh_of(&v, k) } else { mesh_of(&before, k) };
            let m = &got[&k];
            assert_eq!((&m.positions, &m.indices), (&want.positions, &want.indices), "{k:?}");
        }
    }
}
