//! The thesis's numbers in one place: the pulse ranges, the sample time,
//! the rate-loop weights, the gyro statistics and the noise levels of the
//! closed loop's Kalman filter.
//!
//! ```
//! use kestrel_tricopter::constants::{GYRO_COVARIANCE, SAMPLE_TIME, pwm};
//! assert_eq!(SAMPLE_TIME, 0.02);
//! assert_eq!(pwm::MOTOR_MAX - pwm::MOTOR_MIN, 1000.0);
//! assert!(GYRO_COVARIANCE[0][0] > 0.0);
//! ```

/// The tricopter's PWM limits (thesis section 6.1.1, (6.5)-(6.6)), in microseconds.
pub mod pwm {
    /// Lowest ESC command.
    pub const MOTOR_MIN: f64 = 1000.0;
    /// Highest ESC command.
    pub const MOTOR_MAX: f64 = 2000.0;
    /// Servo command at the centre.
    pub const SERVO_CENTER: f64 = 1500.0;
    /// Servo travel either side of the centre.
    pub const SERVO_TRAVEL: f64 = 300.0;
}

/// Sample time of the rate loop (s): 50 Hz.
pub const SAMPLE_TIME: f64 = 0.02;

/// The rate-error weight `Q1 = 2000 I` of [`crate::default_weights`] (per (rad/s)^2).
pub const RATE_WEIGHT: f64 = 2000.0;

/// The pulse weight `Q2 = 0.01 I` of [`crate::default_weights`] (per us^2).
pub const PULSE_WEIGHT: f64 = 0.01;

/// The thesis's gyro measurement covariance (7.6), (rad/s)^2.
pub const GYRO_COVARIANCE: [[f64; 3]; 3] = kestrel_tricopter_model::THESIS_GYRO_COVARIANCE;

/// The thesis's gyro bias (7.5), rad/s.
pub const GYRO_BIAS: [f64; 3] = kestrel_tricopter_model::THESIS_GYRO_BIAS;

/// Process noise of the closed loop's Kalman filter through the inputs:
/// standard deviation per pulse and sample (us).
pub const INPUT_NOISE_US: f64 = 20.0;

/// Process noise of the closed loop's Kalman filter on the outputs' state
/// directions (the gusts): standard deviation per sample (rad/s).
pub const GUST_NOISE: f64 = 0.02;

/// Random walk of the constant disturbance states of an offset-free
/// design: standard deviation per sample.
pub const DISTURBANCE_WALK: f64 = 0.005;
