//! Work per period of the firmware's 16-bit explicit MPC (host model of
//! the AVR walk, what decides its cycles):
//!
//! ```sh
//! cargo run --release -p kestrel-tricopter --example empc16_profile
//! TREE=sampled cargo run --release -p kestrel-tricopter --example empc16_profile   # or noclip, sampled-noclip
//! THETAS=thetas.txt cargo run --release -p kestrel-tricopter --example empc16_profile
//! ```
//!
//! Builds the design's explicit controller (the identified model, N = 2,
//! Ns = 1; the tree method and clipping from `TREE`), quantises it
//! (`quantize_tree`) and walks it at 2000 parameters of the box (the
//! firmware's on-target check's generator) or at the parameters of the
//! file `THETAS` (one period per line, nine numbers `[x; r; throttle]`),
//! counting per period: nodes, rows evaluated (dense and short), their
//! terms, and the cache hits of the node and leaf row requests. The
//! walk's law is checked against `Empc16Law::evaluate_raw`. On the AVR a
//! dense row costs about 350 cycles, a node about 85 besides its rows, a
//! cached row about 30 (crates/avr-rt/README.md).

use kestrel_avr_rt::explicit::quantize::quantize_tree;
use kestrel_avr_rt::explicit::tree16::{Empc16Law, LEAF, NONE, Tree16};
use kestrel_core::formats::SsModel;
use kestrel_empc::tree::TreeMethod;
use kestrel_tricopter::firmware::{DesignSettings, FirmwareDesign};
use std::collections::BTreeMap;

/// Counts over all periods.
#[derive(Default, Debug)]
struct Counts {
    nodes: usize,
    own_row_nodes: usize,
    rows: usize,
    dense_rows: usize,
    terms: usize,
    node_requests: usize,
    node_hits: usize,
    leaf_requests: usize,
    leaf_hits: usize,
}

fn main() {
    let model = SsModel::from_json_str(kestrel_tricopter::IDENTIFIED_MODEL_JSON).expect("model");
    let d = FirmwareDesign::from_model(&model, &DesignSettings::default()).expect("design");
    let solution = kestrel_empc::solve(&d.problem, &kestrel_empc::Settings::default()).unwrap();
    let variant = std::env::var("TREE").unwrap_or_default();
    let mut ts = kestrel_empc::TreeSettings {
        outputs: kestrel_empc::Outputs::First(4),
        ..Default::default()
    };
    if variant.contains("sampled") {
        ts.method = TreeMethod::Sampled;
    }
    if variant.contains("noclip") {
        ts.clipping = false;
    }
    let c = kestrel_empc::build_controller(&d.problem, &solution, &ts).expect("tree");
    let q = quantize_tree(&c.tables).expect("16-bit table");
    let (l, b) = (q.layout, &q.bytes);
    println!("tree {variant:?}: {:?}", c.stats);
    println!("{l:?}: {} bytes", b.len());

    let row_at = |r: usize| l.rows_at() + r * l.row_bytes();
    let terms = |r: usize| l.n_params.saturating_sub(b[row_at(r)] as usize);
    let mut by_terms = vec![0usize; l.n_params + 1];
    for r in 0..l.n_rows {
        by_terms[terms(r)] += 1;
    }
    println!("rows by stored terms (0..={}): {by_terms:?}", l.n_params);

    let flight: Vec<[f64; 9]> = std::env::var("THETAS")
        .map(|p| {
            std::fs::read_to_string(p)
                .expect("THETAS file")
                .lines()
                .map(|line| {
                    let v: Vec<f64> = line
                        .split_whitespace()
                        .map(|x| x.parse().expect("a number"))
                        .collect();
                    std::array::from_fn(|j| v[j])
                })
                .collect()
        })
        .unwrap_or_default();
    let n = if flight.is_empty() {
        2000
    } else {
        flight.len()
    };
    let tree = Tree16::new(&b[..], l).unwrap();
    let mut law = Empc16Law::<f64, _, 9, 4, 256>::new(tree, 5).unwrap();
    let mut seed = 0x2545_f491u32;
    let mut st = Counts::default();
    let mut paths: BTreeMap<(usize, usize, usize), usize> = BTreeMap::new();
    for k in 0..n {
        let th = match flight.get(k) {
            Some(t) => law.quantize(t).unwrap().0,
            None => law.box_sample(&mut seed),
        };
        let value = |r: usize| -> i32 {
            let at = row_at(r);
            let start = b[at] as usize;
            let mut acc = i32::from_le_bytes(b[at + 1..at + 5].try_into().unwrap());
            for (j, t) in th.iter().enumerate().skip(start) {
                let g = at + 5 + 2 * (j - start);
                acc = acc.wrapping_add(i32::from(i16::from_le_bytes([b[g], b[g + 1]])) * *t as i32);
            }
            acc
        };
        let mut cache: Vec<Option<i32>> = vec![None; l.n_rows];
        let (nodes0, rows0) = (st.nodes, st.rows);
        let mut get = |r: usize, st: &mut Counts, leaf: bool| -> i32 {
            let hit = cache[r].is_some();
            if leaf {
                st.leaf_requests += 1;
                st.leaf_hits += usize::from(hit);
            } else {
                st.node_requests += 1;
                st.node_hits += usize::from(hit);
            }
            *cache[r].get_or_insert_with(|| {
                st.rows += 1;
                st.terms += terms(r);
                st.dense_rows += usize::from(terms(r) == l.n_params);
                value(r)
            })
        };
        let mut code = l.root;
        while code & LEAF == 0 {
            let at = l.nodes_at() + 5 * code as usize;
            let nd = &b[at..at + 5];
            st.nodes += 1;
            let a = get(nd[0] as usize, &mut st, false);
            let bv = if nd[1] == NONE {
                st.own_row_nodes += 1;
                0
            } else {
                get(nd[1] as usize, &mut st, false)
            };
            code = if a <= bv {
                if nd[2] == NONE {
                    code + 1
                } else {
                    LEAF | u16::from(nd[2])
                }
            } else {
                u16::from_le_bytes([nd[3], nd[4]])
            };
        }
        let leaf = usize::from(code & !LEAF);
        for o in 0..l.n_outputs {
            for k in 0..2 {
                let r = b[l.bounds_at() + 2 * o + k];
                if r != NONE {
                    get(r as usize, &mut st, true);
                }
            }
            get(
                b[l.laws_at() + l.n_outputs * leaf + o] as usize,
                &mut st,
                true,
            );
        }
        *paths
            .entry((leaf, st.nodes - nodes0, st.rows - rows0))
            .or_insert(0) += 1;
        assert_eq!(law.evaluate_raw(&th).unwrap().law as usize, leaf);
    }
    let f = |v: usize| v as f64 / n as f64;
    println!(
        "{} periods ({}): nodes {:.2} (own-row nodes {:.2}), rows {:.2} (dense {:.2}), terms {:.2}; node row requests {:.2} (cached {:.2}), leaf row requests {:.2} (cached {:.2})",
        n,
        if flight.is_empty() {
            "box samples"
        } else {
            "THETAS"
        },
        f(st.nodes),
        f(st.own_row_nodes),
        f(st.rows),
        f(st.dense_rows),
        f(st.terms),
        f(st.node_requests),
        f(st.node_hits),
        f(st.leaf_requests),
        f(st.leaf_hits),
    );
    let mut top: Vec<_> = paths.into_iter().collect();
    top.sort_by_key(|p| std::cmp::Reverse(p.1));
    top.truncate(6);
    println!("most frequent (law, nodes, rows evaluated): periods {top:?}");
}
