//! Walk state, and its lane view.
//!
//! A wave holds a fixed number of walk slots. The hot state of a slot (depth,
//! direction, throughput, channel ratios, counters, flags, random state, the
//! first link of the adjoint chain) is one record of [`REC`] floats, laid out
//! in blocks of eight fields so that a stage loads only the blocks it uses:
//! loading a chunk is a few vector loads and in-register transposes
//! ([`Wide::load8`]), which makes each block a structure-of-arrays tile of
//! the chunk's walks. Cold columns (queue key, output slot, query, the rest
//! of the chain) are read by index.
//!
//! A slot's `key` says which queue it is in: interface `i` (`key = i`),
//! scattering layer `l` (`key = n + l`), or [`FREE`].

use crate::estimator::events::{ChainLink, Connection, WalkStart};
use crate::lane::{load16, LaneMask, Rgb, Wide, LANE_IDS, MAX_LANES, V3};
use crate::rng::LaneRng;

/// The key of an empty slot.
pub const FREE: u16 = u16::MAX;

/// Floats per walk record (a multiple of 16, so both lane widths tile it).
pub const REC: usize = 48;

/// The record, in blocks of eight fields (the order [`Chunk::gather`] and
/// [`Chunk::scatter`] use):
///
/// | block | fields | loaded by |
/// |---|---|---|
/// | 0 | direction (3), throughput (3), events, specular | every stage |
/// | 1 | random state (4), first, hero, collisions, depth | every stage |
/// | 2 | channel ratios (3), contribution (3), chain length, – | layer events, eval |
/// | 3 | first link: direction (3), factor (3), MIS density, layer | eval |
/// | 4 | first link: transmittance (3), start; `wo` (3), exit | eval |
///
/// `LINK0` is the first field of block 3.
const LINK0: usize = 24;

/// One segment of a walk's adjoint chain, with the transmittance of a full
/// crossing of its layer (what a surface vertex connects through).
#[derive(Clone, Copy, Debug)]
pub struct Link {
    /// The connection.
    pub conn: Connection<f32>,
    /// Transmittance of the whole layer along `conn.u`.
    pub t_full: Rgb<f32>,
    /// The layer the segment crosses.
    pub layer: u16,
    /// The interface it starts from.
    pub start: u16,
}

/// A link in lanes (the engines' shared [`ChainLink`]).
pub type LinkLanes<W> = ChainLink<W>;

/// One walk's record, aligned to a cache line: its [`REC`] floats span whole
/// lines, so none of the eight-float rows a chunk loads straddles two. (With
/// the allocator's 16-byte alignment, which rows straddled depends on where
/// a wave happens to be allocated, and two-thread throughput with it.)
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Record([f32; REC]);

// `Walks::recs` relies on this: no padding in or after the floats.
const _: () = assert!(std::mem::size_of::<Record>() == REC * 4);

impl<W: Wide> LinkLanes<W> {
    /// The link as twelve fields, in the order of a walk record's blocks 3
    /// and 4: direction (3), factor (3), MIS density, layer, full-crossing
    /// transmittance (3), start.
    #[inline(always)]
    pub fn fields(&self) -> [W; 12] {
        let (u, v, t) = (self.conn.u, self.conn.v, self.t);
        [
            u.x,
            u.y,
            u.z,
            v.r,
            v.g,
            v.b,
            self.conn.mis_pdf,
            self.layer,
            t.r,
            t.g,
            t.b,
            self.start,
        ]
    }

    /// The link from its [`LinkLanes::fields`] (the first twelve of `f`).
    #[inline(always)]
    pub fn from_fields(f: &[W]) -> Self {
        LinkLanes {
            conn: Connection {
                u: V3::new(f[0], f[1], f[2]),
                v: Rgb::new(f[3], f[4], f[5]),
                mis_pdf: f[6],
            },
            layer: f[7],
            t: Rgb::new(f[8], f[9], f[10]),
            start: f[11],
        }
    }

    /// No link: a harmless direction and factor 0 (until a launch samples one).
    #[inline(always)]
    pub fn none() -> Self {
        LinkLanes {
            conn: Connection {
                u: V3::z_axis(),
                v: Rgb::zero(),
                mis_pdf: W::zero(),
            },
            t: Rgb::one(),
            layer: W::zero(),
            start: W::zero(),
        }
    }
}

/// One index per lane from the items of a chunk (at most
/// [`MAX_LANES`]): lane `j` takes `f(chunk[j])`, and idle lanes past the
/// chunk's end repeat its last item, so that they load a real walk's values.
/// (A fixed-length loop: a copy of the chunk's length was a call to memmove.)
#[inline(always)]
pub fn lane_ids<T: Copy>(chunk: &[T], f: impl Fn(T) -> u32) -> [u32; MAX_LANES] {
    std::array::from_fn(|j| f(chunk[j.min(chunk.len() - 1)]))
}

/// Eight fields of every lane, one row per lane (row `j`: lane `j`'s
/// fields; rows past `W::LANES` are zero): how a chunk hands values to code
/// that goes lane by lane.
#[inline(always)]
pub fn lane_rows<W: Wide>(fields: [W; 8]) -> [[f32; 8]; MAX_LANES] {
    let mut rows = [[0.0f32; 8]; MAX_LANES];
    W::store8(fields, &mut rows[..W::LANES], &LANE_IDS[..W::LANES], 0);
    rows
}

/// The walks of one wave.
#[derive(Debug, Default)]
pub struct Walks {
    /// Queue key per slot.
    pub key: Vec<u16>,
    /// The walk's index in its task (its output slot).
    pub walk: Vec<u32>,
    /// The walk's query (index into the batch's prepared queries).
    pub query: Vec<u32>,
    /// Hot state, one record per slot (see [`Walks::recs`]).
    rec: Vec<Record>,
    /// The adjoint chain's links after the first (smooth exits only).
    pub chain: Vec<Vec<Link>>,
    /// Slots in use: the columns may be longer, kept from a larger wave
    /// this thread ran before ([`Walks::set_slots`]).
    slots: usize,
}

impl Walks {
    /// A wave of `slots` empty slots.
    pub fn new(slots: usize) -> Self {
        // Block 3 onwards: no link yet (a harmless direction, factor 0).
        let mut rec = [0.0f32; REC];
        rec[LINK0..LINK0 + 12].copy_from_slice(&LinkLanes::<f32>::none().fields());
        Walks {
            key: vec![FREE; slots],
            walk: vec![0; slots],
            query: vec![0; slots],
            rec: vec![Record(rec); slots],
            chain: vec![Vec::new(); slots],
            slots,
        }
    }

    /// Number of slots.
    pub fn slots(&self) -> usize {
        self.slots
    }

    /// Uses `slots` slots: a wave kept for reuse serves a smaller one
    /// without reallocating, and keeps its columns (and the capacity of its
    /// chains) for a larger one later. Grows the columns if they are short.
    pub fn set_slots(&mut self, slots: usize) {
        if slots > self.key.len() {
            let more = Walks::new(slots - self.key.len());
            self.key.extend(more.key);
            self.walk.extend(more.walk);
            self.query.extend(more.query);
            self.rec.extend(more.rec);
            self.chain.extend(more.chain);
        }
        self.slots = slots;
    }

    /// Slots the columns hold, in use or not.
    pub fn capacity(&self) -> usize {
        self.key.len()
    }

    /// The records as float arrays, one per slot.
    pub fn recs(&self) -> &[[f32; REC]] {
        // SAFETY: `Record` is `repr(C)` around a `[f32; REC]` and has no
        // padding (asserted above), so `len` records are `len` float arrays
        // at the same address; the borrow of `self.rec` covers the result.
        unsafe { std::slice::from_raw_parts(self.rec.as_ptr().cast(), self.rec.len()) }
    }

    /// [`Walks::recs`], mutable.
    pub fn recs_mut(&mut self) -> &mut [[f32; REC]] {
        // SAFETY: as in `recs`, with the unique borrow of `self.rec`.
        unsafe { std::slice::from_raw_parts_mut(self.rec.as_mut_ptr().cast(), self.rec.len()) }
    }

    /// Gives slot `s` to walk `walk` of query `query`, waiting for interface
    /// `key`. Its record is written when the walk first leaves the lanes it
    /// starts in ([`Chunk::start`], [`Chunk::scatter`]).
    pub fn claim(&mut self, s: usize, key: u16, walk: u32, query: u32) {
        self.key[s] = key;
        self.walk[s] = walk;
        self.query[s] = query;
        self.chain[s].clear();
    }
}

/// The hot state of up to `W::LANES` walks, in lanes.
#[derive(Clone, Copy)]
pub struct Chunk<W: Wide> {
    /// Lanes holding a walk of this chunk (a partial chunk has fewer).
    pub active: W::Mask,
    /// Depth.
    pub z: W,
    /// Travel direction.
    pub d: V3<W>,
    /// Throughput.
    pub beta: Rgb<W>,
    /// Channel ratios.
    pub ratios: Rgb<W>,
    /// Hero channel.
    pub hero: W,
    /// Events so far.
    pub events: W,
    /// Collisions so far.
    pub order: W,
    /// At the entrance vertex.
    pub first: W::Mask,
    /// Every event so far was a delta.
    pub specular: W::Mask,
    /// Accumulated contribution.
    pub acc: Rgb<W>,
    /// Random state.
    pub rng: LaneRng<W>,
    /// Links in the adjoint chain.
    pub links: W,
    /// The chain's first link.
    pub link0: LinkLanes<W>,
    /// The query's outgoing direction (eval).
    pub wo: V3<W>,
    /// The query's exit interface (eval).
    pub e_out: W,
    /// Blocks of the record loaded so far: 2 (ratios, contribution, chain
    /// length) and 3–4 (the chain's first link, `wo`).
    loaded: (bool, bool),
    /// New eval walks, started in lanes: blocks 3–4 (the chain's first link,
    /// `wo`) are not in the record yet, so [`Chunk::scatter`] stores them too.
    new_link: bool,
}

/// Which stage a chunk is loaded for: each loads and stores only the blocks
/// of the record it uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// An interface event.
    Interface {
        /// The walks accumulate a contribution (eval).
        acc: bool,
        /// Some walk may connect to the viewer here (the chain's links).
        links: bool,
    },
    /// A layer event.
    Layer {
        /// The walks accumulate a contribution (eval).
        acc: bool,
        /// Some walk may connect to the viewer here (the chain's links).
        links: bool,
    },
}

impl Stage {
    /// Blocks loaded: 0 and 1 always; 2 (ratios, contribution, chain length)
    /// for layer events and eval; 3 and 4 (the chain's first link, `wo`)
    /// where walks may connect. Blocks 3 and 4 are only read after a walk's
    /// start: [`Chunk::scatter`] stores them for a fresh chunk only.
    #[inline(always)]
    fn blocks(self) -> (bool, bool) {
        match self {
            Stage::Interface { acc, links } => (acc, links),
            Stage::Layer { links, .. } => (true, links),
        }
    }
}

impl<W: Wide> Chunk<W> {
    /// Loads slots `idx` (exactly `W::LANES` entries; lanes beyond `active`
    /// repeat an active lane's slot, [`lane_ids`], and are overwritten by it
    /// on the way back).
    #[cfg_attr(not(feature = "profiling"), inline(always))]
    #[cfg_attr(feature = "profiling", inline(never))]
    pub fn gather(ws: &Walks, idx: &[u32], active: W::Mask, stage: Stage) -> Self {
        let half = W::splat(0.5);
        let b0 = W::load8(ws.recs(), idx, 0);
        let b1 = W::load8(ws.recs(), idx, 8);
        let mut c = Chunk {
            active,
            d: V3::new(b0[0], b0[1], b0[2]),
            beta: Rgb::new(b0[3], b0[4], b0[5]),
            events: b0[6],
            specular: b0[7].gt(half),
            rng: LaneRng::from_bits(std::array::from_fn(|k| b1[k].to_bit_lanes())),
            first: b1[4].gt(half),
            hero: b1[5],
            order: b1[6],
            z: b1[7],
            ratios: Rgb::one(),
            acc: Rgb::zero(),
            links: W::zero(),
            link0: LinkLanes::none(),
            wo: V3::z_axis(),
            e_out: W::zero(),
            loaded: (false, false),
            new_link: false,
        };
        c.ensure(ws, idx, stage);
        c
    }

    /// New walks in lanes, without touching their records: travelling along
    /// `d` with throughput 1, no events, random state `rng` (whose first
    /// uniform picks the hero channel, as in the scalar walk), and the
    /// query's `wo` and exit `e_out` (`eval`). The chain's first link is for
    /// the caller to sample.
    #[inline(always)]
    pub fn start(
        active: W::Mask,
        d: V3<W>,
        wo: V3<W>,
        e_out: W,
        eval: bool,
        mut rng: LaneRng<W>,
    ) -> Self {
        let s = WalkStart::<W>::new(rng.uniform(active));
        Chunk {
            active,
            z: W::zero(),
            d,
            beta: s.beta,
            ratios: s.ratios,
            hero: s.hero,
            events: s.events,
            order: s.order,
            first: W::Mask::splat(true),
            specular: s.specular,
            acc: Rgb::zero(),
            rng,
            links: W::zero(),
            link0: LinkLanes::none(),
            wo,
            e_out,
            loaded: (true, true),
            new_link: eval,
        }
    }

    /// Loads the blocks `stage` uses that are not loaded yet (a chunk that
    /// stays in lanes for several events may need more as it goes).
    #[cfg_attr(not(feature = "profiling"), inline(always))]
    #[cfg_attr(feature = "profiling", inline(never))]
    pub fn ensure(&mut self, ws: &Walks, idx: &[u32], stage: Stage) {
        let (block2, links) = stage.blocks();
        if block2 && !self.loaded.0 {
            let b2 = W::load8(ws.recs(), idx, 16);
            self.ratios = Rgb::new(b2[0], b2[1], b2[2]);
            self.acc = Rgb::new(b2[3], b2[4], b2[5]);
            self.links = b2[6];
            self.loaded.0 = true;
        }
        if links && !self.loaded.1 {
            let f = load16::<W, REC>(ws.recs(), idx, LINK0);
            self.link0 = LinkLanes::from_fields(&f);
            self.wo = V3::new(f[12], f[13], f[14]);
            self.e_out = f[15];
            self.loaded.1 = true;
        }
    }

    /// Stores the chunk back (every lane; see [`Wide::store8`]): blocks 0–1,
    /// block 2 if loaded, and blocks 3–4 (the chain's first link, `wo`) only
    /// for new eval walks: no stage changes them after a walk's start.
    #[cfg_attr(not(feature = "profiling"), inline(always))]
    #[cfg_attr(feature = "profiling", inline(never))]
    pub fn scatter(&self, ws: &mut Walks, idx: &[u32]) {
        let flag = |m: W::Mask| W::select(m, W::one(), W::zero());
        let (d, b) = (self.d, self.beta);
        let b0 = [
            d.x,
            d.y,
            d.z,
            b.r,
            b.g,
            b.b,
            self.events,
            flag(self.specular),
        ];
        W::store8(b0, ws.recs_mut(), idx, 0);
        let r = self.rng.to_bits().map(W::from_bit_lanes);
        let b1 = [
            r[0],
            r[1],
            r[2],
            r[3],
            flag(self.first),
            self.hero,
            self.order,
            self.z,
        ];
        W::store8(b1, ws.recs_mut(), idx, 8);
        if self.loaded.0 {
            let (r, a) = (self.ratios, self.acc);
            let b2 = [r.r, r.g, r.b, a.r, a.g, a.b, self.links, W::zero()];
            W::store8(b2, ws.recs_mut(), idx, 16);
        }
        if self.new_link {
            let f = self.link0.fields();
            let b3 = std::array::from_fn(|k| f[k]);
            W::store8(b3, ws.recs_mut(), idx, LINK0);
            let w = self.wo;
            let b4 = [f[8], f[9], f[10], f[11], w.x, w.y, w.z, self.e_out];
            W::store8(b4, ws.recs_mut(), idx, LINK0 + 8);
        }
    }

    /// The lanes set in `m`.
    #[inline]
    pub fn lanes(m: W::Mask) -> impl Iterator<Item = usize> {
        let bits = W::bitmask(m);
        (0..W::LANES).filter(move |j| bits & (1 << j) != 0)
    }

    /// The lanes set in `bits`, in increasing order, one step per set bit
    /// (not per lane: for sparse masks, fewer branches to mispredict).
    #[inline]
    pub fn set_bits(mut bits: u32) -> impl Iterator<Item = usize> {
        std::iter::from_fn(move || {
            (bits != 0).then(|| {
                let j = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                j
            })
        })
    }
}
