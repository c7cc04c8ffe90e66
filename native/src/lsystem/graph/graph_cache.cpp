// A thread's LRU cache of expanded graph nodes (lsystem/graph/graph_cache.h).
#include "lsystem/graph/graph_cache.h"

#include <algorithm>

namespace plm::lsystem {

void ExpansionCache::end_trace(const GraphClasses& g) {
  epoch_ = 0;
  for (const auto& t : transient_) {
    Memo& m = memo_[t.first];
    if (m.transient) m = {false, 0, {}, 0, nullptr, false, m.freq};
  }
  transient_.clear();
  trim(g);
}

void ExpansionCache::reset() {
  lru_.clear();
  map_.clear();
  memo_.clear();
  bytes_ = peak_ = 0;
  transient_.clear();
  lookups_ = 0;
  hits_ = misses_ = evictions_ = bypassed_ = 0;
}

const GraphExpansion* ExpansionCache::lookup(const GraphClasses& g, const CacheKey& key) {
  Memo& memo = memo_[key.cls];
  const auto it = map_.find(key);
  if (it != map_.end()) {
    ++hits_;
    it->second->stamp = epoch_;
    lru_.splice(lru_.begin(), lru_, it->second);
    memo = {true, key.path, it->second, epoch_, it->second->e.get(), false, memo.freq};
    return memo.e;
  }
  ++misses_;
  std::shared_ptr<GraphExpansion> made = g.expand(key.cls, key.path);
  made->bytes = expansion_bytes(*made);
  std::shared_ptr<const GraphExpansion> e = std::move(made);
  if (epoch_ != 0 && !admit(g, key.cls, e->bytes)) {
    ++bypassed_;
    transient_.emplace_back(key.cls, std::move(e));
    memo = {true, key.path, {}, epoch_, transient_.back().second.get(), true, memo.freq};
    return memo.e;
  }
  lru_.push_front(Entry{key, std::move(e), epoch_});
  map_.emplace(key, lru_.begin());
  memo = {true, key.path, lru_.begin(), epoch_, lru_.front().e.get(), false, memo.freq};
  bytes_ += lru_.front().e->bytes;
  peak_ = std::max(peak_, bytes_);
  trim(g);  // never evicts the new entry: it carries the running traversal's stamp
  return memo.e;
}

void ExpansionCache::view(const GraphClasses& g, GraphExpansion* e, uint32_t cls, uint64_t path) {
  const size_t before = e->bytes;
  build_view(g, scratch_, e, cls, path);
  if (!memo_[cls].transient) {
    bytes_ = bytes_ - before + e->bytes;
    peak_ = std::max(peak_, bytes_);
  }
}

// Admission (scan resistance): a miss is cached when the cache has room for
// it, or when its class was looked up more often lately than the class of the
// entry it would evict first; otherwise it is held for the running traversal
// only. Frequencies count lookups per class (hits and misses), halved every
// 16 lookups per class.
bool ExpansionCache::admit(const GraphClasses& g, uint32_t cls, size_t bytes) const {
  const bool full = (g.opt.cache_bytes && bytes_ + bytes > g.opt.cache_bytes) ||
                    (g.opt.cache_entries && lru_.size() + 1 > g.opt.cache_entries);
  if (!full || lru_.empty() || lru_.back().stamp == epoch_) return true;
  return memo_[cls].freq > memo_[lru_.back().key.cls].freq;
}

bool ExpansionCache::over(const GraphClasses& g) const {
  return lru_.size() > 1 && ((g.opt.cache_entries && lru_.size() > g.opt.cache_entries) ||
                             (g.opt.cache_bytes && bytes_ > g.opt.cache_bytes));
}

// Evicts least recently used entries that the running traversal did not touch.
void ExpansionCache::trim(const GraphClasses& g) {
  while (over(g) && (epoch_ == 0 || lru_.back().stamp != epoch_)) {
    const CacheKey gone = lru_.back().key;
    Memo& m = memo_[gone.cls];
    if (m.valid && m.path == gone.path) m.valid = false;
    bytes_ -= lru_.back().e->bytes;
    map_.erase(gone);
    lru_.pop_back();
    ++evictions_;
  }
}

}  // namespace plm::lsystem
