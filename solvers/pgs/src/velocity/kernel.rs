//! Sweeps compiled for the instruction set detected at run time: the operations that
//! [`dispatch`] runs, and the batch kernels they run with.

#[cfg(target_arch = "x86_64")]
use super::avx2;
use super::{Batch, LaneSweep, Vel, sweep_batch};

/// An operation of [`dispatch`]: sweeps compiled for one instruction set, running their
/// batches with that set's [`BatchKernel`].
pub(crate) trait KernelOp {
    /// What the operation returns.
    type Output;
    /// Runs the operation with `kernel`.
    fn run<K: BatchKernel>(self, kernel: K) -> Self::Output;
}

/// Runs `op` compiled for `arch` (its kernels inlined): with AVX2 detected, with the
/// intrinsics kernel of [`avx2`]; otherwise with the portable loop, which the compiler
/// vectorises for the set as it can. Both give the same bits.
#[inline]
pub(crate) fn dispatch<Op: KernelOp>(arch: pulp::Arch, op: Op) -> Op::Output {
    #[cfg(target_arch = "x86_64")]
    if let pulp::Arch::V3(simd) = arch {
        return <pulp::x86::V3 as pulp::Simd>::vectorize(simd, WithKernel(op, simd));
    }
    arch.dispatch(WithKernel(op, Portable))
}

/// [`dispatch`]'s operation with its kernel, as [`pulp::WithSimd`] wants it.
struct WithKernel<Op, K>(Op, K);

impl<Op: KernelOp, K: BatchKernel> pulp::WithSimd for WithKernel<Op, K> {
    type Output = Op::Output;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Self::Output {
        self.0.run(self.1)
    }
}

/// How a sweep runs a [`Batch`]: the portable loop ([`sweep_batch`], which the compiler
/// vectorises as it can) or, with AVX2 detected, the same operations written out in its
/// intrinsics ([`avx2`]). Both give the same bits.
pub(crate) trait BatchKernel: Copy {
    /// Sweeps the batches of one colour in order on `vel`, folding their measures into
    /// `lanes`.
    fn sweep<const CONTACT: bool>(self, b: &mut [Batch], vel: &mut [Vel], lanes: &mut LaneSweep);

    /// Sweeps all the batches of two islands, each in order on its own velocities and into
    /// its own measures (the portable loop: one island, then the other).
    #[inline(always)]
    fn sweep_two<const CONTACT: bool>(self, a: Island<'_>, b: Island<'_>) {
        for batch in a.batches {
            sweep_batch::<CONTACT, _>(batch, a.vel, a.lanes);
        }
        for batch in b.batches {
            sweep_batch::<CONTACT, _>(batch, b.vel, b.lanes);
        }
    }
}

/// One island's batches (all of them, colour after colour), velocities and measures, for
/// [`BatchKernel::sweep_two`].
pub(crate) struct Island<'a> {
    pub(crate) batches: &'a mut [Batch],
    pub(crate) vel: &'a mut [Vel],
    pub(crate) lanes: &'a mut LaneSweep,
}

/// [`BatchKernel`] of the portable loop.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Portable;

impl BatchKernel for Portable {
    #[inline(always)]
    fn sweep<const CONTACT: bool>(self, b: &mut [Batch], vel: &mut [Vel], lanes: &mut LaneSweep) {
        for batch in b {
            sweep_batch::<CONTACT, _>(batch, vel, lanes);
        }
    }
}

#[cfg(target_arch = "x86_64")]
impl BatchKernel for pulp::x86::V3 {
    #[inline(always)]
    fn sweep<const CONTACT: bool>(self, b: &mut [Batch], vel: &mut [Vel], lanes: &mut LaneSweep) {
        avx2::sweep_colour::<CONTACT>(self, b, vel, lanes);
    }

    #[inline(always)]
    fn sweep_two<const CONTACT: bool>(self, a: Island<'_>, b: Island<'_>) {
        avx2::sweep_two::<CONTACT>(self, a, b);
    }
}
