//! The slice calls allocate nothing when they run query by query (on the
//! scalar engine, which `Engine::Auto` picks for calls of fewer walks than
//! the wavefront has lanes, or by a closed form), nor as serial wavefront
//! batches (`threads(1)`): counted by a global allocator, after a first call
//! has set up the thread's buffers. Parallel batches allocate inside rayon
//! (docs/embedding.md).

#[path = "common/batches.rs"]
#[allow(dead_code)]
mod batches;
use batches::{Batches, Buffers};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use strata_bsdf::{
    AlbedoRecord, Engine, EvalRecord, LayeredBsdf, SampleRecord, Transport, Vectors, VectorsMut,
};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator, counting calls.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the caller's guarantees are passed on unchanged.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(p, l) }
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

fn allocations(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    f();
    ALLOCATIONS.load(Ordering::SeqCst) - before
}

// One test function: the counter is global, so nothing else may run at once.
#[test]
fn slice_calls_allocate_nothing() {
    let coated = include_str!("../materials/coated_copper.toml");
    let slab = include_str!("../materials/scattering_slab.toml");
    let clear = include_str!("../materials/clear_coat_lambertian.toml");
    // Three interfaces: `Auto` answers eval with the bidirectional estimator.
    let three = include_str!("../materials/three_interfaces.toml");
    let wi = [[0.3f32, 0.0, 0.95], [0.1, -0.4, 0.9], [0.2, 0.2, -0.9]];
    let wo = [[-0.3f32, 0.1, 0.95], [0.5, 0.0, 0.8], [0.0, 0.3, 0.9]];
    // The global pool's worker threads allocate as they start, on their
    // own, whenever that is (the first call that asks for the pool starts
    // them): a parallel batch first makes sure they have, so that the
    // counter sees only the calls measured.
    {
        let stack = strata_bsdf::LayerStack::from_toml_str(slab).unwrap();
        let b = LayeredBsdf::new(stack)
            .engine(Engine::Wavefront)
            .samples(64);
        let pairs = vec![
            (
                glam::Vec3::new(0.3, 0.0, 0.95),
                glam::Vec3::new(0.0, 0.3, 0.9)
            );
            512
        ];
        b.eval_batch(&pairs).unwrap();
    }
    for toml in [coated, slab, clear, three] {
        for transport in [Transport::Radiance, Transport::Importance] {
            let stack = strata_bsdf::LayerStack::from_toml_str(toml).unwrap();
            let b = LayeredBsdf::new(stack)
                .samples(64)
                .engine(Engine::Scalar)
                .transport(transport);
            let mut f = [[0.0f32; 3]; 3];
            let mut rec = [EvalRecord::default(); 3];
            let mut s = [SampleRecord::default(); 3];
            let mut p = [0.0f32; 3];
            let (mut so, mut sw) = ([[0.0f32; 3]; 3], [[0.0f32; 3]; 3]);
            let (mut sp, mut sf) = ([0.0f32; 3], [0u32; 3]);
            let mut run = || {
                b.eval_buffers(
                    Vectors::Aos(&wi),
                    Vectors::Aos(&wo),
                    None,
                    VectorsMut::Aos(&mut f),
                    None,
                )
                .unwrap();
                b.eval_records(
                    Vectors::Aos(&wi),
                    Vectors::Aos(&wo),
                    Some(&[1, 2, 3]),
                    &mut rec,
                )
                .unwrap();
                b.sample_records(Vectors::Aos(&wi), None, &mut s).unwrap();
                b.sample_buffers(
                    Vectors::Aos(&wi),
                    Some(&[4, 5, 6]),
                    VectorsMut::Aos(&mut so),
                    VectorsMut::Aos(&mut sw),
                    &mut sp,
                    &mut sf,
                )
                .unwrap();
                b.pdf_buffers(Vectors::Aos(&wi), Vectors::Aos(&wo), &mut p)
                    .unwrap();
                b.eval_pdf_buffers(
                    Vectors::Aos(&wi),
                    Vectors::Aos(&wo),
                    Some(&[7, 8, 9]),
                    VectorsMut::Aos(&mut f),
                    None,
                    &mut p,
                )
                .unwrap();
            };
            run(); // sets up the thread's chain buffer
            assert_eq!(allocations(&mut run), 0, "{toml}");
            assert!(f.iter().flatten().any(|&x| x > 0.0));
            // (The three walks of the sampler on three interfaces are
            // absorbed: there the eval, bidirectional, is the point.)
            assert!(s.iter().any(|r| r.flags != 0) || toml == three, "{toml}");
        }
    }
    // A single sample and a single pdf on Auto (the scalar engine's walk,
    // the pdf on the wavefront from buffers the thread keeps).
    let stack = strata_bsdf::LayerStack::from_toml_str(coated).unwrap();
    let b = LayeredBsdf::new(stack);
    let mut s = [SampleRecord::default(); 1];
    let mut p = [0.0f32; 1];
    let mut one = || {
        b.sample_records(Vectors::Aos(&wi[..1]), Some(&[9]), &mut s)
            .unwrap();
        b.pdf_buffers(Vectors::Aos(&wi[..1]), Vectors::Aos(&wo[..1]), &mut p)
            .unwrap();
    };
    one();
    assert_eq!(allocations(&mut one), 0);
    // Serial wavefront batches: nothing after a first call as large, for
    // every slice call, on every material and in both modes.
    // Larger than a wave (512 walk slots) many times over: every batch
    // below spans several waves.
    let n = 1024;
    let wi: Vec<[f32; 3]> = (0..n)
        .map(|i| {
            let t = i as f32 / n as f32;
            // Some queries lit from below (opaque stacks: no light enters).
            let z = if i % 3 == 2 { -0.9 } else { 0.9 };
            [0.6 * t - 0.3, 0.2, z]
        })
        .collect();
    let wo: Vec<[f32; 3]> = (0..n)
        .map(|i| {
            let t = i as f32 / n as f32;
            let z = if i % 5 == 4 { -0.9 } else { 0.9 };
            [0.1, 0.5 * t - 0.2, z]
        })
        .collect();
    let keys: Vec<u64> = (0..n as u64).collect();
    let mut f = vec![[0.0f32; 3]; n];
    let mut rec = vec![EvalRecord::default(); n];
    let mut s = vec![SampleRecord::default(); n];
    let (mut so, mut sw) = (vec![[0.0f32; 3]; n], vec![[0.0f32; 3]; n]);
    let (mut sp, mut sf) = (vec![0.0f32; n], vec![0u32; n]);
    let mut a = vec![AlbedoRecord::default(); n];
    let mut pd = vec![0.0f32; n];
    for toml in [coated, slab, clear, three] {
        for transport in [Transport::Radiance, Transport::Importance] {
            let stack = strata_bsdf::LayerStack::from_toml_str(toml).unwrap();
            let b = LayeredBsdf::new(stack)
                .samples(64)
                .engine(Engine::Wavefront)
                .transport(transport)
                .threads(1)
                .unwrap();
            // eval_into, eval_records, sample_records, sample_into, albedo_records, pdf_into,
            // eval_pdf_into.
            let mut calls = |m: usize| {
                [
                    allocations(|| {
                        b.eval_buffers(
                            Vectors::Aos(&wi[..m]),
                            Vectors::Aos(&wo[..m]),
                            None,
                            VectorsMut::Aos(&mut f[..m]),
                            None,
                        )
                        .unwrap();
                    }),
                    allocations(|| {
                        b.eval_records(
                            Vectors::Aos(&wi[..m]),
                            Vectors::Aos(&wo[..m]),
                            Some(&keys[..m]),
                            &mut rec[..m],
                        )
                        .unwrap();
                    }),
                    allocations(|| {
                        b.sample_records(Vectors::Aos(&wi[..m]), None, &mut s[..m])
                            .unwrap()
                    }),
                    allocations(|| {
                        b.sample_buffers(
                            Vectors::Aos(&wi[..m]),
                            Some(&keys[..m]),
                            VectorsMut::Aos(&mut so[..m]),
                            VectorsMut::Aos(&mut sw[..m]),
                            &mut sp[..m],
                            &mut sf[..m],
                        )
                        .unwrap()
                    }),
                    allocations(|| {
                        b.albedo_records(Vectors::Aos(&wi[..m]), 64, None, &mut a[..m])
                            .unwrap();
                    }),
                    allocations(|| {
                        b.pdf_buffers(Vectors::Aos(&wi[..m]), Vectors::Aos(&wo[..m]), &mut pd[..m])
                            .unwrap()
                    }),
                    allocations(|| {
                        b.eval_pdf_buffers(
                            Vectors::Aos(&wi[..m]),
                            Vectors::Aos(&wo[..m]),
                            Some(&keys[..m]),
                            VectorsMut::Aos(&mut f[..m]),
                            None,
                            &mut pd[..m],
                        )
                        .unwrap();
                    }),
                ]
            };
            let what = format!("{transport:?}, {toml}");
            // A first call sets up the thread's buffers; the second allocates
            // nothing, and neither does a smaller batch after a larger one.
            calls(64);
            assert_eq!(calls(64), [0; 7], "64 queries, {what}");
            calls(n);
            assert_eq!(calls(n), [0; 7], "{n} queries, {what}");
            assert_eq!(calls(64), [0; 7], "64 after {n} queries, {what}");
            assert!(f.iter().flatten().any(|&x| x > 0.0));
            assert!(s.iter().any(|r| r.flags != 0) && sf.iter().any(|&x| x != 0));
            assert!(a.iter().any(|r| r.reflected[0] > 0.0));
            assert!(pd.iter().all(|&p| p >= 0.0) && pd.iter().any(|&p| p > 0.0));
        }
    }
    // A wavefront call of at most 256 walks runs on the calling thread
    // whatever the pool: nothing either.
    let stack = strata_bsdf::LayerStack::from_toml_str(slab).unwrap();
    let b = LayeredBsdf::new(stack)
        .engine(Engine::Wavefront)
        .samples(64);
    // The global pool's worker threads allocate as they start, on their
    // own, whenever that is: a parallel batch first makes sure they have,
    // so that the counter sees only the calls measured.
    let (wis, wos) = (Vectors::Aos(&wi), Vectors::Aos(&wo));
    b.eval_records(wis, wos, None, &mut rec).unwrap();
    let mut small = || {
        [
            allocations(|| {
                let (wi, wo) = (Vectors::Aos(&wi[..4]), Vectors::Aos(&wo[..4]));
                b.eval_records(wi, wo, None, &mut rec[..4]).unwrap();
            }),
            allocations(|| {
                b.sample_records(Vectors::Aos(&wi[..64]), None, &mut s[..64])
                    .unwrap()
            }),
            allocations(|| {
                b.albedo_records(Vectors::Aos(&wi[..4]), 64, None, &mut a[..4])
                    .unwrap();
            }),
        ]
    };
    small();
    assert_eq!(small(), [0; 3], "eval, sample and albedo of 256 walks");
    // Parallel batches allocate inside rayon: the count is not zero (so the
    // counter counts), and does not grow with the batch in proportion.
    let stack = strata_bsdf::LayerStack::from_toml_str(coated).unwrap();
    let b = LayeredBsdf::new(stack);
    let b = b.engine(Engine::Wavefront).samples(64).threads(2).unwrap();
    let (wi4, wo4) = (vec![wi[0]; 4096], vec![wo[0]; 4096]);
    let mut f = vec![[0.0f32; 3]; 4096];
    let mut eval = |n: usize| {
        allocations(|| {
            b.eval_buffers(
                Vectors::Aos(&wi4[..n]),
                Vectors::Aos(&wo4[..n]),
                None,
                VectorsMut::Aos(&mut f[..n]),
                None,
            )
            .unwrap();
        })
    };
    let (small, large) = (eval(16), eval(4096));
    assert!(
        small > 0 && large < 4096 / 2,
        "{small} and {large} allocations"
    );
}
