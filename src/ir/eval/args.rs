//! An argument block as the evaluator's frames read it ([`ArgBlock`]): the 32-bit words a
//! kernel reads, laid out by `abi::ArgLayout`, floats among them as f32 bits.
//!
//! A float word is read as a lane word of the run's precision: widened from its f32 bits,
//! unless the evaluator filled it itself from an F64 value (a primitive call's argument),
//! in which case that exact value is kept beside the word and read instead, so an F64
//! run's floats do not pass through f32 at a call. The word itself always holds what the
//! JIT's block would: the value rounded to f32.

use std::collections::HashMap;

use super::Precision;

pub(crate) struct ArgBlock {
    words: Vec<u32>,
    /// Lane words of the float words filled from F64 values, by word index.
    exact: HashMap<usize, u64>,
}

impl ArgBlock {
    pub(crate) fn new(words: Vec<u32>) -> ArgBlock {
        ArgBlock {
            words,
            exact: HashMap::new(),
        }
    }

    pub(crate) fn len(&self) -> usize {
        self.words.len()
    }

    /// Word `i` as the kernel reads it.
    pub(crate) fn word(&self, i: usize) -> Option<u32> {
        self.words.get(i).copied()
    }

    /// The number of sequence points (word 0; 0 for an empty block).
    pub(crate) fn n_seq(&self) -> u32 {
        self.word(0).unwrap_or(0)
    }

    /// Float word `i` as a lane word of precision `p`.
    pub(crate) fn float(&self, i: usize, p: Precision) -> Option<u64> {
        match self.exact.get(&i) {
            Some(&w) => Some(w),
            None => self.word(i).map(|w| p.from_f32(f32::from_bits(w))),
        }
    }

    /// Word `i` as a lane word: a float word (`float`) in precision `p`, any other
    /// zero-extended.
    pub(crate) fn lane_word(&self, i: usize, float: bool, p: Precision) -> Option<u64> {
        if float {
            self.float(i, p)
        } else {
            self.word(i).map(u64::from)
        }
    }

    /// Set word `i` (false when the block has none).
    pub(crate) fn set(&mut self, i: usize, w: u32) -> bool {
        self.exact.remove(&i);
        match self.words.get_mut(i) {
            Some(slot) => {
                *slot = w;
                true
            }
            None => false,
        }
    }

    /// Set float word `i` from lane word `w` of precision `p` (false when the block has
    /// none).
    pub(crate) fn set_float(&mut self, i: usize, w: u64, p: Precision) -> bool {
        match p {
            Precision::F32 => self.set(i, w as u32),
            Precision::F64 => {
                let set = self.set(i, p.to_f32(w).to_bits());
                if set {
                    self.exact.insert(i, w);
                }
                set
            }
        }
    }

    /// Copy word `from` of `src` (and its exact value) to word `to` (false when either
    /// block has no such word).
    pub(crate) fn copy(&mut self, src: &ArgBlock, from: usize, to: usize) -> bool {
        let Some(w) = src.word(from) else { return false };
        if !self.set(to, w) {
            return false;
        }
        if let Some(&x) = src.exact.get(&from) {
            self.exact.insert(to, x);
        }
        true
    }
}
