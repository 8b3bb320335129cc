//! The stages of a wave: launch, interface events, layer events; and the
//! round loop that sorts walks into queues between them.
//!
//! Each stage mirrors one part of the scalar reference's walk
//! (`estimator::scalar`) operation for operation, with masks where the scalar
//! code returns early.

use super::walks::{Chunk, Link, Walks, FREE};
use super::{Mode, Queries, Stats, Unit, WalkOut, Wavefront};
use crate::estimator::events::{self, Connection};
use crate::estimator::layout::{depth_to_boundary, move_depth, LayerKind, Next};
use crate::estimator::pdf::{mix_uniform, pdf_walk};
use crate::estimator::scalar::MAX_CHAIN;
use crate::interface::InterfaceLanes;
use crate::lane::{Lane, LaneMask, Rgb, Wide, V3};
use crate::medium;
use crate::rng::{seed_state, LaneRng, Stream};

/// A wave during one task: the walks, the task's outputs, the free slots.
struct Wave<'a> {
    ws: &'a mut Walks,
    out: &'a mut [WalkOut],
    free: Vec<u32>,
    live: usize,
}

impl Wave<'_> {
    /// Ends the walk in `slot` with `o` and frees the slot.
    fn finish(&mut self, slot: u32, o: WalkOut) {
        let s = slot as usize;
        self.out[self.ws.walk[s] as usize] = o;
        self.ws.key[s] = FREE;
        self.ws.chain[s].clear();
        self.free.push(slot);
        self.live -= 1;
    }
}

/// Lane `j` of a connection, as f32.
fn conn_lane<W: Wide>(c: &Connection<W>, j: usize) -> Connection<f32> {
    let f = |x: W| x.lane(j) as f32;
    Connection {
        u: V3::new(f(c.u.x), f(c.u.y), f(c.u.z)),
        v: Rgb::new(f(c.v.r), f(c.v.g), f(c.v.b)),
        mis_pdf: f(c.mis_pdf),
    }
}

/// Lane `j` of an RGB triple, as f32.
fn rgb_lane<W: Wide>(c: Rgb<W>, j: usize) -> Rgb<f32> {
    Rgb::new(c.r.lane(j) as f32, c.g.lane(j) as f32, c.b.lane(j) as f32)
}

/// Builds lanes from one f32 link per lane.
fn links_to_lanes<W: Wide>(links: &[Link]) -> (Connection<W>, Rgb<W>) {
    let v = |f: &dyn Fn(&Link) -> f32| W::from_fn(|j| f(&links[j]) as f64);
    (
        Connection {
            u: V3::new(v(&|k| k.conn.u.x), v(&|k| k.conn.u.y), v(&|k| k.conn.u.z)),
            v: Rgb::new(v(&|k| k.conn.v.r), v(&|k| k.conn.v.g), v(&|k| k.conn.v.b)),
            mis_pdf: v(&|k| k.conn.mis_pdf),
        },
        Rgb::new(v(&|k| k.t_full.r), v(&|k| k.t_full.g), v(&|k| k.t_full.b)),
    )
}

/// A link that connects nothing (for lanes without one).
const NO_LINK: Link = Link {
    conn: Connection {
        u: V3 {
            x: 0.0,
            y: 0.0,
            z: 1.0,
        },
        v: Rgb {
            r: 0.0,
            g: 0.0,
            b: 0.0,
        },
        mis_pdf: 0.0,
    },
    t_full: Rgb {
        r: 1.0,
        g: 1.0,
        b: 1.0,
    },
    layer: u16::MAX,
    start: u16::MAX,
};

impl<W: Wide> Wavefront<W> {
    /// Runs every walk of `task` in the wave `ws`; outputs go to `out` in
    /// task order.
    pub(super) fn run_task(
        &self,
        q: &Queries,
        task: &[Unit],
        ws: &mut Walks,
        out: &mut Vec<WalkOut>,
    ) -> Stats {
        let total: usize = task.iter().map(|u| u.count as usize).sum();
        out.clear();
        out.resize(total, WalkOut::default());
        let slots = ws.slots();
        ws.key.fill(FREE);
        let mut wave = Wave {
            ws,
            out,
            free: (0..slots as u32).rev().collect(),
            live: 0,
        };
        let n = self.layout.n;
        let nkeys = 2 * n - 1;
        let mut stats = Stats {
            walks: total as u64,
            ..Stats::default()
        };
        let (mut unit, mut offset, mut w) = (0usize, 0u32, 0u32);
        let mut launched: Vec<(u32, u64)> = Vec::with_capacity(slots);
        let mut counts = vec![0usize; nkeys + 1];
        let mut order = vec![0u32; slots];
        loop {
            // Refill free slots with the next walks.
            launched.clear();
            while unit < task.len() {
                let Some(slot) = wave.free.pop() else { break };
                let u = task[unit];
                let k = u.first + offset as u64;
                self.init_walk(q, wave.ws, slot, u.query, w, k);
                launched.push((slot, k));
                w += 1;
                offset += 1;
                if offset == u.count {
                    unit += 1;
                    offset = 0;
                }
            }
            wave.live += launched.len();
            self.launch(q, wave.ws, &launched);
            if wave.live == 0 {
                break;
            }
            // Sort live slots into queues by key (counting sort, stable).
            counts.fill(0);
            for &k in &wave.ws.key {
                if k != FREE {
                    counts[k as usize + 1] += 1;
                }
            }
            for k in 0..nkeys {
                counts[k + 1] += counts[k];
            }
            let starts = counts.clone();
            for (s, &k) in wave.ws.key.iter().enumerate() {
                if k != FREE {
                    order[counts[k as usize]] = s as u32;
                    counts[k as usize] += 1;
                }
            }
            // Advance every queue by one event, a chunk of lanes at a time.
            for key in 0..nkeys {
                let queue = &order[starts[key]..starts[key + 1]];
                for chunk in queue.chunks(W::LANES) {
                    let mut idx = [chunk[0]; 64];
                    idx[..chunk.len()].copy_from_slice(chunk);
                    let idx = &idx[..W::LANES];
                    let active = W::mask_from_bitmask(lane_bits(chunk.len()));
                    stats.chunks += 1;
                    stats.lanes += W::LANES as u64;
                    stats.segments += chunk.len() as u64;
                    if key < n {
                        self.interface_stage(q, &mut wave, idx, active, key);
                    } else {
                        self.layer_stage(q, &mut wave, idx, active, key - n);
                    }
                }
            }
        }
        stats
    }

    /// Writes a new walk's scalar state into `slot`.
    fn init_walk(&self, q: &Queries, ws: &mut Walks, slot: u32, query: u32, w: u32, k: u64) {
        let s = slot as usize;
        let qi = query as usize;
        ws.key[s] = q.e_in[qi];
        ws.walk[s] = w;
        ws.query[s] = query;
        ws.z[s] = 0.0;
        for c in 0..3 {
            ws.d[c][s] = -q.wi[c][qi];
            ws.beta[c][s] = 1.0;
            ws.ratios[c][s] = 1.0;
            ws.acc[c][s] = 0.0;
        }
        ws.events[s] = 0.0;
        ws.order[s] = 0.0;
        ws.first[s] = 1.0;
        ws.specular[s] = 1.0;
        let st = seed_state(q.seed, q.key[qi], k, Stream::Walk);
        for (c, v) in st.into_iter().enumerate() {
            ws.rng[c][s] = v;
        }
        ws.chain[s].clear();
    }

    /// The lane part of starting walks: the hero channel and (eval) the
    /// adjoint chain.
    fn launch(&self, q: &Queries, ws: &mut Walks, launched: &[(u32, u64)]) {
        for chunk in launched.chunks(W::LANES) {
            let mut idx = [chunk[0].0; 64];
            for (j, &(s, _)) in chunk.iter().enumerate() {
                idx[j] = s;
            }
            let idx = &idx[..W::LANES];
            let active = W::mask_from_bitmask(lane_bits(chunk.len()));
            let mut rng = LaneRng::<W>::gather(&ws.rng, idx);
            let hero = events::hero_channel(rng.uniform(active));
            hero.scatter(&mut ws.hero, idx, active);
            rng.scatter(&mut ws.rng, idx, active);
            if q.mode == Mode::Eval && self.layout.n >= 2 {
                self.launch_chains(q, ws, chunk, idx, active);
            }
        }
    }

    /// Samples the adjoint chains of new eval walks (scalar:
    /// `ScalarEngine::adjoint_chain`).
    fn launch_chains(
        &self,
        q: &Queries,
        ws: &mut Walks,
        chunk: &[(u32, u64)],
        idx: &[u32],
        active: W::Mask,
    ) {
        let n = self.layout.n;
        let qs: Vec<u32> = idx.iter().map(|&s| ws.query[s as usize]).collect();
        let states: [Vec<u32>; 4] = {
            let st: Vec<[u32; 4]> = (0..W::LANES)
                .map(|j| {
                    let (_, k) = chunk[j.min(chunk.len() - 1)];
                    seed_state(q.seed, q.key[qs[j] as usize], k, Stream::Adjoint)
                })
                .collect();
            std::array::from_fn(|c| st.iter().map(|s| s[c]).collect())
        };
        let lidx: Vec<u32> = (0..W::LANES as u32).collect();
        let mut rng = LaneRng::<W>::gather(&states, &lidx);
        let wo = V3::new(
            W::gather(&q.wo[0], &qs),
            W::gather(&q.wo[1], &qs),
            W::gather(&q.wo[2], &qs),
        );
        let e_out = W::gather(&q.e_out, &qs);
        let exit = InterfaceLanes::<W>::gather(&self.table, |j| e_out.lane(j) as usize);
        let u = (
            rng.uniform(active),
            rng.uniform(active),
            rng.uniform(active),
        );
        let (conn, ok) = events::chain_start(&exit, wo, u);
        let mut alive = ok & active & exit.smooth;
        for j in Chunk::<W>::lanes(ok & active) {
            let e = e_out.lane(j) as usize;
            let (layer, start) = self.layout.exit_region(e).expect("n >= 2");
            let c = conn_lane(&conn, j);
            ws.chain[idx[j] as usize].push(self.link(c, layer, start));
        }
        // Continue through delta interfaces while the chain stays smooth.
        let mut events_n = 1u32;
        let mut len = 1usize;
        while alive.any() && len < MAX_CHAIN {
            let lasts: Vec<Link> = (0..W::LANES)
                .map(|j| {
                    if alive.lane(j) {
                        *ws.chain[idx[j] as usize].last().expect("chain started")
                    } else {
                        NO_LINK
                    }
                })
                .collect();
            let jj: Vec<usize> = lasts
                .iter()
                .map(|k| {
                    if k.start == u16::MAX {
                        0
                    } else {
                        k.start as usize
                    }
                })
                .collect();
            let iface = InterfaceLanes::<W>::gather(&self.table, |j| jj[j]);
            let cont = alive & iface.smooth;
            if !cont.any() {
                break;
            }
            let (last, t) = links_to_lanes::<W>(&lasts);
            let u = (rng.uniform(cont), rng.uniform(cont), rng.uniform(cont));
            let (c2, ok2) = events::chain_step(&iface, &last, t, u);
            let up = c2.u.z.lt(W::zero());
            let mut next_alive = cont & ok2;
            let jl = W::from_fn(|j| jj[j] as f64);
            let out = W::select(up, jl, W::splat(n as f64 - 1.0) - jl).eq(W::zero());
            next_alive = next_alive & !out;
            events_n += 1;
            let ur = rng.uniform(next_alive);
            let (v, surv) = events::roulette(
                c2.v,
                W::splat(events_n as f64),
                ur,
                self.settings.rr_start,
                None,
            );
            next_alive = next_alive & surv;
            let c2 = Connection { v, ..c2 };
            for j in Chunk::<W>::lanes(next_alive) {
                let lane_up = up.lane(j);
                let Next::Layer { l, .. } = self.layout.next(jj[j], lane_up) else {
                    unreachable!("exits were masked out")
                };
                let start = self.layout.boundary(l, lane_up);
                ws.chain[idx[j] as usize].push(self.link(conn_lane(&c2, j), l, start));
            }
            alive = next_alive;
            len += 1;
        }
    }

    /// A chain link with its full-crossing transmittance (f32, as the scalar
    /// engine computes it at each use).
    fn link(&self, conn: Connection<f32>, layer: usize, start: usize) -> Link {
        let m = &self.media_f32[layer];
        Link {
            conn,
            t_full: m.transmittance(m.thickness, conn.u.z.abs()),
            layer: layer as u16,
            start: start as u16,
        }
    }

    /// Lanes of the chunk's walks' `k`-th links (or [`NO_LINK`]), and whether
    /// any lane has one.
    fn links_k(ws: &Walks, idx: &[u32], active: W::Mask, k: usize) -> Option<Vec<Link>> {
        let mut any = false;
        let links = (0..W::LANES)
            .map(|j| match ws.chain[idx[j] as usize].get(k) {
                Some(l) if active.lane(j) => {
                    any = true;
                    *l
                }
                _ => NO_LINK,
            })
            .collect();
        any.then_some(links)
    }

    /// Per-lane query directions and exits for eval.
    fn query_lanes(q: &Queries, ws: &Walks, idx: &[u32]) -> (V3<W>, W) {
        let qs: Vec<u32> = idx.iter().map(|&s| ws.query[s as usize]).collect();
        let wo = V3::new(
            W::gather(&q.wo[0], &qs),
            W::gather(&q.wo[1], &qs),
            W::gather(&q.wo[2], &qs),
        );
        (wo, W::gather(&q.e_out, &qs))
    }

    /// The exits a walk of this stack can leave through, with their regions.
    fn exits(&self) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
        let n = self.layout.n;
        let last = if self.stack.transmissive() && n > 1 {
            vec![0, n - 1]
        } else {
            vec![0]
        };
        last.into_iter().filter_map(move |e| {
            let (l0, k0) = self.layout.exit_region(e)?;
            (!self.stack.interface(e).smooth).then_some((e, l0, k0))
        })
    }

    /// One interface event for a chunk of walks at interface `i`.
    fn interface_stage(
        &self,
        q: &Queries,
        wave: &mut Wave,
        idx: &[u32],
        active: W::Mask,
        i: usize,
    ) {
        let n = self.layout.n;
        let eval = q.mode == Mode::Eval;
        let mis = self.settings.mis;
        let mut c = Chunk::<W>::gather(wave.ws, idx, active);
        let iface = &self.ifaces[i];
        let a = -c.d;
        let (wo, e_out) = if eval {
            Self::query_lanes(q, wave.ws, idx)
        } else {
            (V3::z_axis(), W::zero())
        };
        // Next-event estimation from this surface vertex.
        if eval {
            let mut k = 0;
            while let Some(links) = Self::links_k(wave.ws, idx, active, k) {
                let starts = W::from_fn(|j| links[j].start as f64);
                let m = active & starts.eq(W::splat(i as f64));
                if m.any() {
                    let (conn, t) = links_to_lanes::<W>(&links);
                    let add = c.beta * events::connect_surface(iface, a, c.first, &conn, t, mis);
                    c.acc = Rgb::select(m, c.acc + add, c.acc);
                }
                k += 1;
            }
        }
        // Scatter at the interface.
        let (us, u1, u2) = (
            c.rng.uniform(active),
            c.rng.uniform(active),
            c.rng.uniform(active),
        );
        let transmit_only = c.first & W::Mask::splat(eval);
        let s = iface.sample(a, us, u1, u2, transmit_only);
        let alive = active & s.valid;
        c.beta = Rgb::select(alive, c.beta * s.weight, c.beta);
        c.specular = c.specular & (s.delta | !alive);
        c.events = W::select(alive, c.events + W::one(), c.events);
        let d = s.b;
        let up = d.z.gt(W::zero());
        // Path continuation towards a rough exit.
        if eval {
            for (e, l0, k0) in self.exits() {
                if k0 != i {
                    continue;
                }
                let m = alive & e_out.eq(W::splat(e as f64)) & toward(d, e);
                if m.any() {
                    let med = &self.media[l0];
                    let t = med.transmittance(med.thickness, d.z.abs());
                    let add = c.beta
                        * events::continue_to_exit(&self.ifaces[e], wo, d, s.pdf, s.delta, t, mis);
                    c.acc = Rgb::select(m, c.acc + add, c.acc);
                }
            }
        }
        c.first = W::Mask::splat(false);
        c.d = V3::select(alive, d, c.d);
        let out_up = W::Mask::splat(i == 0);
        let out_dn = W::Mask::splat(i + 1 == n);
        let exited = alive & ((up & out_up) | (!up & out_dn));
        let mut cont = alive & !exited;
        // Russian roulette.
        let u = c.rng.uniform(cont);
        let (b2, surv) = events::walk_roulette(c.beta, c.events, u, &self.settings);
        c.beta = Rgb::select(cont, b2, c.beta);
        cont = cont & surv;
        // Enter the next layer; cross the ones that do not scatter right here.
        let mut stuck = W::Mask::splat(false);
        let mut keys = [FREE; 2]; // [up, down]
        for (dir, going_up) in [(0usize, true), (1, false)] {
            let Next::Layer { l, .. } = self.layout.next(i, going_up) else {
                continue;
            };
            let m = cont & if going_up { up } else { !up };
            let med = &self.media[l];
            let entry = if going_up { med.thickness } else { W::zero() };
            if med.kind == LayerKind::Scattering {
                keys[dir] = (n + l) as u16;
                c.z = W::select(m, entry, c.z);
                continue;
            }
            keys[dir] = self.layout.boundary(l, going_up) as u16;
            if !m.any() {
                continue;
            }
            let mu = d.z.abs();
            let flat = m & mu.le(W::zero());
            stuck = stuck | flat;
            if med.kind == LayerKind::Absorbing {
                let ok = m & !flat;
                let dz = depth_to_boundary(entry, med.thickness, W::Mask::splat(going_up));
                c.beta = Rgb::select(ok, c.beta * med.transmittance(dz, mu), c.beta);
            }
        }
        c.scatter(wave.ws, idx);
        for j in Chunk::<W>::lanes(active) {
            let slot = idx[j];
            if exited.lane(j) {
                let o = self.exit_out(q, wave.ws, slot, &c, j);
                wave.finish(slot, o);
            } else if !cont.lane(j) || stuck.lane(j) {
                let o = self.dead_out(&c, j);
                wave.finish(slot, o);
            } else {
                wave.ws.key[slot as usize] = keys[if up.lane(j) { 0 } else { 1 }];
            }
        }
    }

    /// One layer event for a chunk of walks inside scattering layer `l`.
    fn layer_stage(&self, q: &Queries, wave: &mut Wave, idx: &[u32], active: W::Mask, l: usize) {
        let eval = q.mode == Mode::Eval;
        let mis = self.settings.mis;
        let mut c = Chunk::<W>::gather(wave.ws, idx, active);
        let med = &self.media[l];
        let h = med.thickness;
        let d = c.d;
        let mu = d.z.abs();
        let flat = active & mu.le(W::zero());
        let moving = active & !flat;
        let up = d.z.gt(W::zero());
        let dz = depth_to_boundary(c.z, h, up);
        let ud = c.rng.uniform(moving);
        let ff = medium::sample_free_flight(
            med.sigma_t,
            med.albedo,
            med.grey,
            W::div_or_zero(dz, mu, moving),
            c.hero,
            ud,
            c.ratios,
        );
        c.beta = Rgb::select(moving, c.beta * ff.weight, c.beta);
        c.ratios = Rgb::select(moving, ff.ratios, c.ratios);
        let pass = moving & !ff.collide;
        let mut col = moving & ff.collide;
        c.order = W::select(col, c.order + W::one(), c.order);
        let over = match self.settings.max_scatter_order {
            Some(k) => col & c.order.gt(W::splat(k as f64)),
            None => W::Mask::splat(false),
        };
        col = col & !over;
        c.z = W::select(col, move_depth(c.z, d.z, ff.distance, h), c.z);
        let (wo, e_out) = if eval {
            Self::query_lanes(q, wave.ws, idx)
        } else {
            (V3::z_axis(), W::zero())
        };
        // Next-event estimation from the collision.
        if eval {
            let mut k = 0;
            while let Some(links) = Self::links_k(wave.ws, idx, col, k) {
                let layers = W::from_fn(|j| links[j].layer as f64);
                let m = col & layers.eq(W::splat(l as f64));
                if m.any() {
                    let (conn, _) = links_to_lanes::<W>(&links);
                    let u = conn.u;
                    let dz_e = depth_to_boundary(c.z, h, u.z.gt(W::zero()));
                    let t = med.transmittance(dz_e, u.z.abs());
                    let add = c.beta * events::connect_collision(med.g, d, &conn, t, mis);
                    c.acc = Rgb::select(m, c.acc + add, c.acc);
                }
                k += 1;
            }
        }
        let u1 = c.rng.uniform(col);
        let u2 = c.rng.uniform(col);
        let dn = medium::hg_sample(med.g, d, u1, u2);
        c.specular = c.specular & !col;
        // Path continuation from the collision towards a rough exit.
        if eval && mis {
            for (e, l0, _) in self.exits() {
                if l0 != l {
                    continue;
                }
                let m = col & e_out.eq(W::splat(e as f64)) & toward(dn, e);
                if m.any() {
                    let dz_e = depth_to_boundary(c.z, h, dn.z.gt(W::zero()));
                    let t = med.transmittance(dz_e, dn.z.abs());
                    let pv = medium::hg_eval(med.g, d.dot(dn));
                    let add = c.beta
                        * events::continue_to_exit(
                            &self.ifaces[e],
                            wo,
                            dn,
                            pv,
                            W::Mask::splat(false),
                            t,
                            mis,
                        );
                    c.acc = Rgb::select(m, c.acc + add, c.acc);
                }
            }
        }
        c.d = V3::select(col, dn, c.d);
        c.events = W::select(col, c.events + W::one(), c.events);
        let u = c.rng.uniform(col);
        let (b2, surv) = events::walk_roulette(c.beta, c.events, u, &self.settings);
        c.beta = Rgb::select(col, b2, c.beta);
        let scattered = col & surv;
        c.scatter(wave.ws, idx);
        let n = self.layout.n;
        for j in Chunk::<W>::lanes(active) {
            let slot = idx[j];
            if pass.lane(j) {
                wave.ws.key[slot as usize] = self.layout.boundary(l, up.lane(j)) as u16;
            } else if scattered.lane(j) {
                wave.ws.key[slot as usize] = (n + l) as u16;
            } else {
                let o = self.dead_out(&c, j);
                wave.finish(slot, o);
            }
        }
    }

    /// The output of a walk that left the stack.
    fn exit_out(&self, q: &Queries, ws: &Walks, slot: u32, c: &Chunk<W>, j: usize) -> WalkOut {
        let qi = ws.query[slot as usize] as usize;
        let d = [
            c.d.x.lane(j) as f32,
            c.d.y.lane(j) as f32,
            c.d.z.lane(j) as f32,
        ];
        let v = if q.mode == Mode::Eval { c.acc } else { c.beta };
        WalkOut {
            value: rgb_lane(v, j).to_array(),
            dir: d,
            exited: true,
            reflection: (d[2] > 0.0) == (q.wi[2][qi] > 0.0),
            specular: c.specular.lane(j),
        }
    }

    /// The output of a walk that ended inside the stack.
    fn dead_out(&self, c: &Chunk<W>, j: usize) -> WalkOut {
        WalkOut {
            value: rgb_lane(c.acc, j).to_array(),
            ..WalkOut::default()
        }
    }

    /// Approximate pdfs of queries `qs`, one query per lane.
    pub(super) fn pdf_queries(&self, q: &Queries, qs: &[usize], samples: u32) -> Vec<f64> {
        let mut res = vec![0.0f64; qs.len()];
        let mut sums = vec![0.0f64; qs.len()];
        if self.layout.n >= 2 && samples > 0 {
            for chunk_start in (0..qs.len()).step_by(W::LANES) {
                let chunk = &qs[chunk_start..(chunk_start + W::LANES).min(qs.len())];
                let lq: Vec<u32> = (0..W::LANES)
                    .map(|j| chunk[j.min(chunk.len() - 1)] as u32)
                    .collect();
                let g = |col: &[f32]| W::gather(col, &lq);
                let wi = V3::new(g(&q.wi[0]), g(&q.wi[1]), g(&q.wi[2]));
                let wo = V3::new(g(&q.wo[0]), g(&q.wo[1]), g(&q.wo[2]));
                let e_in = W::from_fn(|j| q.e_in[lq[j] as usize] as f64);
                let e_out = g(&q.e_out);
                for k in 0..samples {
                    let states: [Vec<u32>; 4] = {
                        let st: Vec<[u32; 4]> = lq
                            .iter()
                            .map(|&qq| {
                                seed_state(q.seed, q.key[qq as usize], k as u64, Stream::Pdf)
                            })
                            .collect();
                        std::array::from_fn(|c| st.iter().map(|s| s[c]).collect())
                    };
                    let lidx: Vec<u32> = (0..W::LANES as u32).collect();
                    let mut rng = LaneRng::<W>::gather(&states, &lidx);
                    let all = W::Mask::splat(true);
                    let p = pdf_walk(&self.table, wi, wo, e_in, e_out, || {
                        (rng.uniform(all), rng.uniform(all), rng.uniform(all))
                    });
                    for j in 0..chunk.len() {
                        sums[chunk_start + j] += p.lane(j);
                    }
                }
            }
        }
        for (k, &qi) in qs.iter().enumerate() {
            if !q.valid[qi] {
                continue;
            }
            let wi = V3::new(q.wi[0][qi], q.wi[1][qi], q.wi[2][qi]);
            let wo = V3::new(q.wo[0][qi], q.wo[1][qi], q.wo[2][qi]);
            let e_in = q.e_in[qi] as usize;
            let mut p = 0.0;
            if e_in == q.e_out[qi] as usize {
                p += self.table[e_in].pdf(wi, wo, false).lane(0);
            }
            if self.layout.n >= 2 && samples > 0 {
                p += sums[k] / samples as f64;
            }
            res[k] = mix_uniform(p);
        }
        res
    }
}

/// Lanes `0..n` set.
fn lane_bits(n: usize) -> u32 {
    if n >= 32 {
        u32::MAX
    } else {
        (1u32 << n) - 1
    }
}

/// Lanes whose direction `d` heads for exit interface `e` (0: the top).
fn toward<W: Wide>(d: V3<W>, e: usize) -> W::Mask {
    if e == 0 {
        d.z.gt(W::zero())
    } else {
        d.z.lt(W::zero())
    }
}
