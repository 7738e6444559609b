// Controller tables, placed in flash (`.text.kestrel_tables`, read with ELPM).
//
// **Interim** controller (kestrel-core only; see `kestrel_avr_rt::interim`),
// designed by hand for the test-local plant of `crates/avr-rt/tests/hil.rs`:
// arm 0.5 m, motors at (0.25, +-0.433) and (-0.5, 0) m, inertia diag(0.02,
// 0.02, 0.035) kg m^2, thrust k_t w^2 with k_t = 1.96e-5, w = w_max (pwm -
// 1000)/1000, w_max = 1000 rad/s (hover at 1500 us: 4.9 N per rotor), drag
// torque 0.02 k_t w^2, tail tilt 0.5/300 rad/us around 1500 us.
// Thrust slope at hover g = 2 k_t w_h w_max/1000 = 0.0196 N/us, so
// - roll:  d1 = -d2 = -tau_x / (0.866 g)       = -58.9 tau_x
// - pitch: d1 = d2 = tau_y / (1.5 g) = 34.0 tau_y, d3 = -68.0 tau_y
// - yaw:   servo = tau_z / (-0.5 T cos(mu0) / 600) = -246.7 tau_z
// - servo trim: sin(mu0) = 3 * 0.02 * 4.9 / (0.5 * 4.9), 1500 + 600 mu0 = 1572.2 us.
// Rate loop: bandwidth 8 rad/s (kp = 8 I), ki = 12 I, observer gain 0.7.
// Gyro bias e_0 from thesis (7.5).

/// Number of f32 values in [`INTERIM_TABLE`].
pub const N_VALUES: usize = 38;

#[rustfmt::skip]
const VALUES: [f32; N_VALUES] = [
    // 0..3 observer measurement gain
    0.7, 0.7, 0.7,
    // 3..6 observer input gain Ts / I
    1.0, 1.0, 0.571_428_6,
    // 6..9 kp (torque per rad/s) = 8 I
    0.16, 0.16, 0.28,
    // 9..12 ki * Ts = 12 I * 0.02
    0.0048, 0.0048, 0.0084,
    // 12..15 integrator limits (N m)
    0.3, 0.3, 0.3,
    // 15..18 gyro bias e_0 (thesis 7.5)
    -9.72e-4, -4.92e-5, 4.27e-3,
    // 18..30 mixer rows ESC1, ESC2, ESC3, servo; columns tau_x, tau_y, tau_z
    -58.9, 34.0, 0.0,
    58.9, 34.0, 0.0,
    0.0, -68.0, 0.0,
    0.0, 0.0, -246.7,
    // 30..34 offsets (us)
    0.0, 0.0, 0.0, 1572.2,
    // 34..38 throttle gains
    1.0, 1.0, 1.0, 0.0,
];

/// The interim controller table (little-endian f32).
#[unsafe(link_section = ".text.kestrel_tables")]
#[used]
pub static INTERIM_TABLE: [u8; 4 * N_VALUES] = kestrel_avr_rt::progmem::f32_bytes(VALUES);
