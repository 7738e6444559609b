//! Unit tests of the certification's parts.

use super::flops::*;

#[test]
fn small_cases() {
    assert_eq!(remove(1, 0), 0);
    assert_eq!(remove(3, 0), 7 * 2 + 2 * 2);
    assert_eq!(add(4, 0, false, 0), 2);
    assert_eq!(add(4, 2, true, 1), 8 * 3 + 4 + 6 + 2);
    assert_eq!(preamble(4), 32);
    assert_eq!(singular(2, 1, 1), 2 + 1 + 2 + 2 + 6);
    assert_eq!(mustar(3, 1), 18 - 1);
    assert_eq!(mustar(2, 5), 4);
    assert_eq!(blocking(2, 1) + dual_step(2), 5 + 6);
    assert_eq!(primal(4, 1) + scan(4, 1, 7), 8 + 8 + 21);
}
