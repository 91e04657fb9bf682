#pragma once
// Keyframe retrieval from binary (ORB) descriptors through an approximate nearest-neighbour index,
// the way vocabulary-free loop detectors scale to many keyframes: every stored descriptor goes
// into one index (FAISS IndexBinaryHNSW, Debian's libfaiss-dev), each query descriptor finds its
// nearest stored descriptors and votes for the keyframes they belong to; the top-voted keyframes
// are then matched and verified as usual (LoopDetector, `retrieval = ann`).
// FAISS stays an implementation detail (pimpl): this header does not include it.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "sparseloop/features/informative_features.h"

namespace sparseloop {

struct BinaryAnnOptions {
  // HNSW graph: links per node (2 * hnsw_m on the bottom level), count >= 2. More links = better
  // recall, more memory (about 8 * hnsw_m bytes per descriptor) and slower inserts.
  int hnsw_m = 16;
  int ef_construction = 40;  // candidate list while inserting, count >= 1
  // Candidate list while searching, count >= neighbors. Recall@1 of a planted neighbour among 20k
  // random descriptors: 0.91 at 32, 0.98 at 64, 0.998 at 128 (tests/retrieval).
  int ef_search = 64;
  int neighbors = 2;  // k nearest stored descriptors per query descriptor, count >= 1
  // A neighbour farther than this votes for nothing, bits in [0, 256] (the same bound as
  // MatchOptions::max_distance).
  int max_distance = 64;
  // Top-voted keyframes a caller (LoopDetector) matches and verifies, count >= 1.
  int max_candidates = 10;
  // OpenMP threads FAISS may use inside Add()/Search(), >= 1. 1 keeps inserts deterministic (HNSW
  // insertion in parallel depends on thread timing); the caller's OpenMP setting is restored.
  int num_threads = 1;
  void Check() const;
};

// One stored descriptor found for a query descriptor.
struct DescriptorNeighbor {
  int64_t keyframe_id = -1;  // keyframe the stored descriptor belongs to
  int descriptor = -1;       // its index inside that keyframe's descriptors
  int distance = 0;          // Hamming distance, bits
};

struct KeyframeVotes {
  int64_t keyframe_id = -1;
  int votes = 0;  // query descriptors with a neighbour (within max_distance) in this keyframe
};

class BinaryAnnIndex {
 public:
  explicit BinaryAnnIndex(BinaryAnnOptions options = {});
  ~BinaryAnnIndex();
  BinaryAnnIndex(BinaryAnnIndex&&) noexcept;
  BinaryAnnIndex& operator=(BinaryAnnIndex&&) noexcept;

  // Indexes the descriptors of one keyframe. Keyframe ids must strictly increase (insertion order
  // is keyframe order). An empty descriptor set is allowed (the keyframe gets no votes).
  void Add(int64_t keyframe_id, std::span<const Descriptor> descriptors);

  // Approximate k nearest stored descriptors of each query descriptor, nearest first (fewer when
  // fewer are stored). Not filtered by max_distance. k >= 1.
  std::vector<std::vector<DescriptorNeighbor>> Search(const std::vector<Descriptor>& query,
                                                      int k) const;

  // Votes: each query descriptor gives one vote to every distinct keyframe among its
  // `options.neighbors` nearest stored descriptors that lie within max_distance. Sorted by votes
  // (descending), then keyframe id (ascending); keyframes without votes are absent.
  std::vector<KeyframeVotes> Query(const std::vector<Descriptor>& query) const;

  const BinaryAnnOptions& options() const { return options_; }
  size_t num_keyframes() const { return keyframe_ids_.size(); }
  size_t num_descriptors() const { return block_start_.empty() ? 0 : block_start_.back(); }
  // Memory held by the index: descriptor codes, HNSW links, level and offset tables, and the
  // descriptor -> keyframe table (vector capacities), bytes. Does not count KeyframeRecords.
  size_t Bytes() const;

 private:
  struct Impl;
  BinaryAnnOptions options_;
  std::unique_ptr<Impl> impl_;
  std::vector<int64_t> keyframe_ids_;  // in insertion order
  // block_start_[i] = first descriptor (FAISS label) of keyframe i; one extra entry at the end.
  std::vector<int64_t> block_start_;
};

// Exact reference (tests, benchmarks): brute-force Hamming k nearest neighbours of each query
// descriptor among `stored`, nearest first, ties by lower index. Returns indices into `stored`;
// `distances` (optional) receives the matching Hamming distances.
std::vector<std::vector<int>> BruteForceKnn(const std::vector<Descriptor>& query,
                                            const std::vector<Descriptor>& stored, int k,
                                            std::vector<std::vector<int>>* distances = nullptr);

}  // namespace sparseloop
