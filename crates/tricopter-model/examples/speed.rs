//! Times raw RK4 steps of the model.
use kestrel_tricopter_model::{Params, Tricopter};
fn main() {
    let m = Tricopter::new(Params::default()).unwrap();
    let trim = m.trim_hover().unwrap();
    let mut x = trim.state;
    let t0 = std::time::Instant::now();
    for _ in 0..250_000 {
        m.step(&mut x, &trim.input, 1e-3).unwrap();
    }
    println!("250k RK4 steps: {:?} {}", t0.elapsed(), x[0]);
    let t0 = std::time::Instant::now();
    let mut acc = 0.0;
    for i in 0..1_000_000 {
        x[6] = i as f64 * 1e-9;
        acc += m.derivative(std::hint::black_box(&x), &trim.input)[9];
    }
    println!("1M derivatives: {:?} {}", t0.elapsed(), acc);
}
