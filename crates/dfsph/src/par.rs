//! The solver's one door to data parallelism.
//!
//! With the default `parallel` feature this re-exports rayon's parallel iterators; without it
//! (`--no-default-features`: WebAssembly, embedding in a program that schedules its own
//! threads) the same calls run as plain sequential iterators on the calling thread, so the
//! solver's passes are written once for both builds.
//!
//! Only the rayon adaptors the solver uses are mirrored; a pass that needs another one adds it
//! here, and the serial build fails to compile until it does.

/// Workers of the pool the caller is in (or would hand work to): rayon's, or 1 in the serial
/// build.
#[inline]
pub(crate) fn current_num_threads() -> usize {
    #[cfg(feature = "parallel")]
    return rayon::current_num_threads();
    #[cfg(not(feature = "parallel"))]
    return 1;
}

/// The calling thread's index in its rayon pool; `None` outside a pool and in the serial
/// build.
#[inline]
pub(crate) fn current_thread_index() -> Option<usize> {
    #[cfg(feature = "parallel")]
    return rayon::current_thread_index();
    #[cfg(not(feature = "parallel"))]
    return None;
}

/// Run `work` as a task of the current pool (so that the passes it forks are pool tasks and
/// its caller sleeps until it ends), or on the calling thread in the serial build.
#[inline]
pub(crate) fn on_a_worker<R: Send>(work: impl FnOnce() -> R + Send) -> R {
    #[cfg(feature = "parallel")]
    return rayon::scope(|_| work());
    #[cfg(not(feature = "parallel"))]
    return work();
}

/// Send `invitation` to every worker of the current pool without waiting for any of them
/// (rayon's `spawn_broadcast`). The serial build has no workers to invite: regions and
/// stand-bys then run on their caller alone, which is always enough to finish them.
#[inline]
pub(crate) fn invite_every_worker(invitation: impl Fn() + Send + Sync + 'static) {
    #[cfg(feature = "parallel")]
    rayon::spawn_broadcast(move |_| invitation());
    #[cfg(not(feature = "parallel"))]
    drop(invitation);
}

#[cfg(feature = "parallel")]
pub(crate) mod prelude {
    pub(crate) use rayon::prelude::*;
}

#[cfg(not(feature = "parallel"))]
pub(crate) mod prelude {
    pub(crate) use super::serial::{
        IndexedParallelIterator, IntoSerialIterator, SerialSlice, SerialSliceMut, SerialVec,
    };
}

#[cfg(not(feature = "parallel"))]
mod serial {
    //! Sequential stand-ins for rayon's parallel-iterator adaptors.

    /// A sequential iterator with rayon's names for the adaptors that differ from
    /// [`Iterator`]'s: `with_min_len` (a split hint, meaningless here) and `reduce` with an
    /// identity (rayon's form). Inherent methods take precedence over `Iterator`'s, so
    /// `map`, `zip` and `enumerate` are mirrored to keep the wrapper through a chain.
    pub(crate) struct Seq<I>(pub(crate) I);

    impl<I: Iterator> Iterator for Seq<I> {
        type Item = I::Item;
        #[inline]
        fn next(&mut self) -> Option<I::Item> {
            self.0.next()
        }
        #[inline]
        fn size_hint(&self) -> (usize, Option<usize>) {
            self.0.size_hint()
        }
    }

    impl<I: ExactSizeIterator> ExactSizeIterator for Seq<I> {}

    /// rayon's bound for iterators of known length.
    pub(crate) trait IndexedParallelIterator: ExactSizeIterator {}
    impl<I: ExactSizeIterator> IndexedParallelIterator for I {}

    impl<I: Iterator> Seq<I> {
        #[inline]
        pub(crate) fn with_min_len(self, _min: usize) -> Self {
            self
        }
        #[inline]
        pub(crate) fn map<B, F: FnMut(I::Item) -> B>(self, f: F) -> Seq<std::iter::Map<I, F>> {
            Seq(self.0.map(f))
        }
        #[inline]
        pub(crate) fn zip<J: IntoIterator>(self, other: J) -> Seq<std::iter::Zip<I, J::IntoIter>> {
            Seq(self.0.zip(other))
        }
        #[inline]
        pub(crate) fn enumerate(self) -> Seq<std::iter::Enumerate<I>> {
            Seq(self.0.enumerate())
        }
        /// rayon's `fold`: one accumulator per split, here one for everything.
        #[inline]
        pub(crate) fn fold<T, ID, F>(self, identity: ID, op: F) -> Seq<std::iter::Once<T>>
        where
            ID: Fn() -> T,
            F: FnMut(T, I::Item) -> T,
        {
            Seq(std::iter::once(self.0.fold(identity(), op)))
        }
        /// rayon's `reduce`: `identity` is the neutral element of `op`.
        #[inline]
        pub(crate) fn reduce<ID, OP>(self, identity: ID, op: OP) -> I::Item
        where
            ID: Fn() -> I::Item,
            OP: Fn(I::Item, I::Item) -> I::Item,
        {
            self.0.fold(identity(), op)
        }
    }

    impl<A, B, I: Iterator<Item = (A, B)>> Seq<I> {
        /// rayon's `unzip_into_vecs`: the vectors are cleared, then filled.
        #[inline]
        pub(crate) fn unzip_into_vecs(self, left: &mut Vec<A>, right: &mut Vec<B>) {
            left.clear();
            right.clear();
            for (a, b) in self.0 {
                left.push(a);
                right.push(b);
            }
        }
    }

    /// `into_par_iter` on anything iterable (ranges, vectors).
    pub(crate) trait IntoSerialIterator: IntoIterator + Sized {
        #[inline]
        fn into_par_iter(self) -> Seq<Self::IntoIter> {
            Seq(self.into_iter())
        }
    }
    impl<T: IntoIterator> IntoSerialIterator for T {}

    /// `par_iter` and `par_chunks` on slices.
    pub(crate) trait SerialSlice<T> {
        fn par_iter(&self) -> Seq<std::slice::Iter<'_, T>>;
        fn par_chunks(&self, size: usize) -> Seq<std::slice::Chunks<'_, T>>;
    }
    impl<T> SerialSlice<T> for [T] {
        #[inline]
        fn par_iter(&self) -> Seq<std::slice::Iter<'_, T>> {
            Seq(self.iter())
        }
        #[inline]
        fn par_chunks(&self, size: usize) -> Seq<std::slice::Chunks<'_, T>> {
            Seq(self.chunks(size))
        }
    }

    /// `par_iter_mut` and `par_chunks_mut` on slices.
    pub(crate) trait SerialSliceMut<T> {
        fn par_iter_mut(&mut self) -> Seq<std::slice::IterMut<'_, T>>;
        fn par_chunks_mut(&mut self, size: usize) -> Seq<std::slice::ChunksMut<'_, T>>;
    }
    impl<T> SerialSliceMut<T> for [T] {
        #[inline]
        fn par_iter_mut(&mut self) -> Seq<std::slice::IterMut<'_, T>> {
            Seq(self.iter_mut())
        }
        #[inline]
        fn par_chunks_mut(&mut self, size: usize) -> Seq<std::slice::ChunksMut<'_, T>> {
            Seq(self.chunks_mut(size))
        }
    }

    /// `par_extend` on vectors.
    pub(crate) trait SerialVec<T> {
        fn par_extend<I: IntoIterator<Item = T>>(&mut self, items: I);
    }
    impl<T> SerialVec<T> for Vec<T> {
        #[inline]
        fn par_extend<I: IntoIterator<Item = T>>(&mut self, items: I) {
            self.extend(items);
        }
    }
}
