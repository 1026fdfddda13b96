//! Kernels are shared across render threads (the JIT itself moves between threads).

use std::sync::Arc;

use primflow::abi::Kernel;

/// Kernels are shared across render threads; the JIT itself moves between threads.
#[test]
fn kernels_are_send_and_sync() {
    fn send_sync<T: Send + Sync>() {}
    send_sync::<Kernel>();
    send_sync::<Arc<Kernel>>();
}
