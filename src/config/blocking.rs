//! The store's blocking flash as the async `NorFlash` that `sequential-storage` works over, and
//! the executor that runs its operations to their end in one poll.

use core::future::Future;
use core::task::{Context, Poll, Waker};
use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};
use embedded_storage_async::nor_flash as asynch;

/// The store's blocking flash as the async `NorFlash` that `sequential-storage` works over:
/// each operation runs when `sequential-storage` asks for it, and its future ([`Done`]) is
/// complete from the start, so a whole map operation finishes in its first poll ([`run`]).
/// (The board's flash is blocking anyway: programming stalls the CPU.)
pub(super) struct Blocking<'f, F>(pub(super) &'f mut F);

/// A flash operation that has already run, as a future: ready with its result at every poll
/// (no state, no "polled after completion" path).
struct Done<E>(Result<(), E>);

impl<E: Copy> Future for Done<E> {
    type Output = Result<(), E>;

    fn poll(self: core::pin::Pin<&mut Self>, _: &mut Context<'_>) -> Poll<Self::Output> {
        Poll::Ready(self.0)
    }
}

impl<F: ErrorType> ErrorType for Blocking<'_, F> {
    type Error = F::Error;
}

impl<F: ReadNorFlash> asynch::ReadNorFlash for Blocking<'_, F>
where
    F::Error: Copy,
{
    const READ_SIZE: usize = F::READ_SIZE;

    fn read(
        &mut self,
        offset: u32,
        bytes: &mut [u8],
    ) -> impl Future<Output = Result<(), F::Error>> {
        Done(read(self.0, offset, bytes))
    }

    fn capacity(&self) -> usize {
        self.0.capacity()
    }
}

/// One out-of-line read for every read `sequential-storage` makes (inlined, each call site
/// carried the driver's bounds check and copy).
#[inline(never)]
pub(super) fn read<F: ReadNorFlash>(
    flash: &mut F,
    offset: u32,
    bytes: &mut [u8],
) -> Result<(), F::Error> {
    flash.read(offset, bytes)
}

impl<F: NorFlash> asynch::NorFlash for Blocking<'_, F>
where
    F::Error: Copy,
{
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> impl Future<Output = Result<(), F::Error>> {
        Done(self.0.erase(from, to))
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> impl Future<Output = Result<(), F::Error>> {
        Done(self.0.write(offset, bytes))
    }
}

/// Runs a `sequential-storage` operation over [`Blocking`] to its end. Its flash futures are
/// complete when created and `sequential-storage` (8.0) awaits nothing but the flash, so the
/// first poll returns `Ready`. Were a later version to await something else, the loop would
/// poll again (a busy wait, as `block_on` does) rather than fail an `unwrap`.
pub(super) fn run<T>(op: impl Future<Output = T>) -> T {
    let mut op = core::pin::pin!(op);
    let mut cx = Context::from_waker(Waker::noop());
    loop {
        if let Poll::Ready(v) = op.as_mut().poll(&mut cx) {
            return v;
        }
    }
}
