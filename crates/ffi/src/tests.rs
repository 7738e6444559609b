//! Tests of the C ABI from Rust.

#[test]
fn sizes() {
    use core::mem::size_of;
    std::println!(
        "kalman {} {} fgm {} {} empc {} {} loop {} {}",
        size_of::<kestrel_avr_rt::kalman16::Kalman16<f32, 5, 4, 3>>(),
        size_of::<kestrel_avr_rt::kalman16::Kalman16<kestrel_avr_rt::mac::Q16Mac, 5, 4, 3>>(),
        size_of::<crate::fgm::Law<f32>>(),
        size_of::<crate::fgm::Law<kestrel_avr_rt::mac::Q16Mac>>(),
        size_of::<crate::empc::Law<f32>>(),
        size_of::<crate::empc::Law<kestrel_avr_rt::mac::Q16Mac>>(),
        size_of::<crate::rate::Loop<f32>>(),
        size_of::<crate::rate::Loop<kestrel_avr_rt::mac::Q16Mac>>(),
    );
}
