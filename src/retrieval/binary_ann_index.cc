#include "sparseloop/retrieval/binary_ann_index.h"

#include <omp.h>

#include <algorithm>
#include <unordered_map>

#include <faiss/IndexBinaryHNSW.h>

#include "sparseloop/core/check.h"

namespace sparseloop {
namespace {

using FaissIdx = faiss::IndexBinary::idx_t;  // FAISS 1.7.3 (bookworm) label type
constexpr int kBits = 256;                   // ORB descriptor length
static_assert(sizeof(Descriptor) == kBits / 8, "Descriptor must be 32 contiguous bytes");

// Sets the OpenMP thread count of the calling thread for FAISS and restores the caller's value.
class ScopedOmpThreads {
 public:
  explicit ScopedOmpThreads(int n) : saved_(omp_get_max_threads()) { omp_set_num_threads(n); }
  ~ScopedOmpThreads() { omp_set_num_threads(saved_); }
  ScopedOmpThreads(const ScopedOmpThreads&) = delete;
  ScopedOmpThreads& operator=(const ScopedOmpThreads&) = delete;

 private:
  int saved_;
};

const uint8_t* Codes(std::span<const Descriptor> d) {
  return reinterpret_cast<const uint8_t*>(d.data());
}

}  // namespace

void BinaryAnnOptions::Check() const {
  // Upper bounds keep the memory per stored descriptor and the cost per query bounded (a value
  // beyond them only costs: recall is saturated far below).
  SL_CHECK_MSG(hnsw_m >= 2 && hnsw_m <= 256, "ann.hnsw_m must be in [2, 256], got {}", hnsw_m);
  SL_CHECK_MSG(ef_construction >= 1 && ef_construction <= 4096,
               "ann.ef_construction must be in [1, 4096], got {}", ef_construction);
  SL_CHECK_MSG(neighbors >= 1 && neighbors <= 256, "ann.neighbors must be in [1, 256], got {}",
               neighbors);
  SL_CHECK_MSG(ef_search >= neighbors, "ann.ef_search ({}) must be >= ann.neighbors ({})",
               ef_search, neighbors);
  SL_CHECK_MSG(ef_search <= 4096, "ann.ef_search must be at most 4096, got {}", ef_search);
  SL_CHECK_MSG(max_distance >= 0 && max_distance <= kBits,
               "ann.max_distance must be in [0, 256] bits, got {}", max_distance);
  SL_CHECK_MSG(max_candidates >= 1, "ann.max_candidates must be >= 1, got {}", max_candidates);
  SL_CHECK_MSG(num_threads >= 1, "ann.num_threads must be >= 1, got {}", num_threads);
}

struct BinaryAnnIndex::Impl {
  explicit Impl(const BinaryAnnOptions& o) : index(kBits, o.hnsw_m) {
    index.hnsw.efConstruction = o.ef_construction;
    index.hnsw.efSearch = o.ef_search;
  }
  faiss::IndexBinaryHNSW index;
};

BinaryAnnIndex::BinaryAnnIndex(BinaryAnnOptions options)
    : options_([&] {
        options.Check();
        return options;
      }()),
      impl_(std::make_unique<Impl>(options_)),
      block_start_{0} {}

BinaryAnnIndex::~BinaryAnnIndex() = default;
BinaryAnnIndex::BinaryAnnIndex(BinaryAnnIndex&&) noexcept = default;
BinaryAnnIndex& BinaryAnnIndex::operator=(BinaryAnnIndex&&) noexcept = default;

void BinaryAnnIndex::Add(int64_t keyframe_id, std::span<const Descriptor> descriptors) {
  SL_CHECK_MSG(impl_, "BinaryAnnIndex used after being moved from");
  SL_CHECK_MSG(keyframe_ids_.empty() || keyframe_id > keyframe_ids_.back(),
               "BinaryAnnIndex::Add: keyframe ids must increase ({} after {})", keyframe_id,
               keyframe_ids_.empty() ? -1 : keyframe_ids_.back());
  if (!descriptors.empty()) {
    ScopedOmpThreads threads(options_.num_threads);
    impl_->index.add(static_cast<FaissIdx>(descriptors.size()), Codes(descriptors));
  }
  keyframe_ids_.push_back(keyframe_id);
  block_start_.push_back(block_start_.back() + static_cast<int64_t>(descriptors.size()));
  SL_CHECK_MSG(impl_->index.ntotal == block_start_.back(),
               "BinaryAnnIndex: FAISS holds {} codes, expected {}", impl_->index.ntotal,
               block_start_.back());
}

std::vector<std::vector<DescriptorNeighbor>> BinaryAnnIndex::Search(
    const std::vector<Descriptor>& query, int k) const {
  SL_CHECK_MSG(impl_, "BinaryAnnIndex used after being moved from");
  SL_CHECK_MSG(k >= 1, "BinaryAnnIndex::Search: k must be >= 1, got {}", k);
  std::vector<std::vector<DescriptorNeighbor>> out(query.size());
  if (query.empty() || num_descriptors() == 0) return out;
  std::vector<int32_t> distances(query.size() * k);
  std::vector<FaissIdx> labels(query.size() * k);
  {
    ScopedOmpThreads threads(options_.num_threads);
    impl_->index.search(static_cast<FaissIdx>(query.size()), Codes(query), k, distances.data(),
                        labels.data());
  }
  for (size_t q = 0; q < query.size(); ++q) {
    auto& row = out[q];
    row.reserve(k);
    for (int j = 0; j < k; ++j) {
      const FaissIdx label = labels[q * k + j];
      if (label < 0) continue;  // fewer results than k
      // The keyframe whose block [block_start_[i], block_start_[i + 1]) holds the label.
      const auto it = std::upper_bound(block_start_.begin(), block_start_.end(), label);
      const size_t i = static_cast<size_t>(it - block_start_.begin()) - 1;
      row.push_back(
          {keyframe_ids_[i], static_cast<int>(label - block_start_[i]), distances[q * k + j]});
    }
    std::stable_sort(row.begin(), row.end(),
                     [](const DescriptorNeighbor& a, const DescriptorNeighbor& b) {
                       return a.distance < b.distance;
                     });
  }
  return out;
}

std::vector<KeyframeVotes> BinaryAnnIndex::Query(const std::vector<Descriptor>& query) const {
  const auto neighbors = Search(query, options_.neighbors);
  std::unordered_map<int64_t, int> votes;
  std::vector<int64_t> voted;  // distinct keyframes of one query descriptor
  for (const auto& row : neighbors) {
    voted.clear();
    for (const auto& n : row) {
      if (n.distance > options_.max_distance) continue;
      if (std::find(voted.begin(), voted.end(), n.keyframe_id) != voted.end()) continue;
      voted.push_back(n.keyframe_id);
      ++votes[n.keyframe_id];
    }
  }
  std::vector<KeyframeVotes> out;
  out.reserve(votes.size());
  for (const auto& [id, v] : votes) out.push_back({id, v});
  std::sort(out.begin(), out.end(), [](const KeyframeVotes& a, const KeyframeVotes& b) {
    return a.votes != b.votes ? a.votes > b.votes : a.keyframe_id < b.keyframe_id;
  });
  return out;
}

size_t BinaryAnnIndex::Bytes() const {
  size_t bytes = sizeof(*this) + keyframe_ids_.capacity() * sizeof(int64_t) +
                 block_start_.capacity() * sizeof(int64_t);
  if (!impl_) return bytes;
  const auto& index = impl_->index;
  const auto& hnsw = index.hnsw;
  bytes += sizeof(Impl);
  if (const auto* flat = dynamic_cast<const faiss::IndexBinaryFlat*>(index.storage))
    bytes += sizeof(*flat) + flat->xb.capacity();
  bytes += hnsw.neighbors.capacity() * sizeof(faiss::HNSW::storage_idx_t) +
           hnsw.levels.capacity() * sizeof(int) + hnsw.offsets.capacity() * sizeof(size_t) +
           hnsw.assign_probas.capacity() * sizeof(double) +
           hnsw.cum_nneighbor_per_level.capacity() * sizeof(int);
  return bytes;
}

std::vector<std::vector<int>> BruteForceKnn(const std::vector<Descriptor>& query,
                                            const std::vector<Descriptor>& stored, int k,
                                            std::vector<std::vector<int>>* distances) {
  SL_CHECK_MSG(k >= 1, "BruteForceKnn: k must be >= 1, got {}", k);
  std::vector<std::vector<int>> out(query.size());
  if (distances) distances->assign(query.size(), {});
  const size_t kk = std::min<size_t>(static_cast<size_t>(k), stored.size());
  std::vector<std::pair<int, int>> all(stored.size());  // (distance, index)
  for (size_t q = 0; q < query.size(); ++q) {
    for (size_t i = 0; i < stored.size(); ++i)
      all[i] = {HammingDistance(query[q], stored[i]), static_cast<int>(i)};
    std::partial_sort(all.begin(), all.begin() + kk, all.end());
    for (size_t j = 0; j < kk; ++j) {
      out[q].push_back(all[j].second);
      if (distances) (*distances)[q].push_back(all[j].first);
    }
  }
  return out;
}

}  // namespace sparseloop
