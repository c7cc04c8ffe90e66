// A thread's LRU cache of expanded graph nodes, with their traversal views.
//
// Entries are keyed by (class, path key) where the class is path dependent,
// else by (class, 0) and shared by all paths; capacities are
// GraphOptions::cache_entries and cache_bytes. A traversal holds plain
// pointers to entries: every entry it looks up is stamped with the
// traversal's number and not evicted before the traversal ends, so a
// capacity below what one ray touches is exceeded by those entries until the
// ray ends (then the cache is trimmed back). A full cache admits a miss only
// if its class was looked up more often lately than the class of the entry
// LRU would evict (otherwise the expansion lives for its traversal only:
// GraphStats::bypassed), so the many cold nodes deep in a plant do not push
// out the nodes most rays visit when the working set exceeds the cache.
// Per-class memos find a class's last entry again without hashing.
#pragma once

#include <cstddef>
#include <cstdint>
#include <list>
#include <memory>
#include <unordered_map>
#include <utility>
#include <vector>

#include "lsystem/graph/graph_classes.h"
#include "lsystem/graph/graph_expansion.h"
#include "lsystem/graph/graph_view.h"
#include "util/rng.h"

namespace plm::lsystem {

struct CacheKey {
  uint32_t cls;
  uint64_t path;
  bool operator==(const CacheKey& o) const { return cls == o.cls && path == o.path; }
};
struct CacheKeyHash {
  size_t operator()(const CacheKey& k) const { return size_t(splitmix64(k.path ^ (uint64_t(k.cls) << 32))); }
};

class ExpansionCache {
 public:
  // A traversal's start and end: entries looked up in between stay until
  // end_trace(), which trims the cache back to its capacity.
  void begin_trace(const GraphClasses& g) {
    epoch_ = ++tick_;
    if (memo_.size() < g.classes.size()) memo_.resize(g.classes.size());
  }
  void end_trace(const GraphClasses& g);

  // The expansion of (cls, path) with its view, for the running traversal:
  // expanded on a miss, its view made on its first use.
  const GraphExpansion* find(const GraphClasses& g, uint32_t cls, uint64_t path, bool path_dependent) {
    const Memo& memo = memo_[cls];
    if (memo.stamp == epoch_ && memo.valid && memo.path == (path_dependent ? path : 0)) {
      ++hits_;
      return memo.e;
    }
    GraphExpansion* e = const_cast<GraphExpansion*>(get(g, cls, path, path_dependent));
    if (!e->has_view) view(g, e, cls, path);  // the thread's own entry: no other thread sees it
    return e;
  }

  // Empties the cache and zeroes the counters.
  void reset();

  uint64_t hits() const { return hits_; }
  uint64_t misses() const { return misses_; }
  uint64_t evictions() const { return evictions_; }
  uint64_t bypassed() const { return bypassed_; }
  size_t entries() const { return lru_.size(); }
  size_t bytes() const { return bytes_; }
  size_t peak_bytes() const { return peak_; }

 private:
  struct Entry {
    CacheKey key;
    std::shared_ptr<const GraphExpansion> e;
    uint64_t stamp;                         // the traversal that last looked it up
  };
  // Per class: the entry of its last lookup (a class that is not path
  // dependent has one entry; valid until evicted).
  struct Memo {
    bool valid = false;
    uint64_t path = 0;
    std::list<Entry>::iterator it;
    uint64_t stamp = 0;                     // it->stamp, read without touching the list
    const GraphExpansion* e = nullptr;      // it->e.get()
    bool transient = false;                 // e is in `transient_`, not in the list (it is not valid)
    uint32_t freq = 0;                      // the class's recent lookups (see admit())
  };

  // The entry of (cls, path), expanded on a miss; stamped with the running
  // traversal. Recency is kept per traversal: an entry moves to the front of
  // the LRU list at its first lookup in a traversal only.
  const GraphExpansion* get(const GraphClasses& g, uint32_t cls, uint64_t path, bool path_dependent) {
    const CacheKey key{cls, path_dependent ? path : 0};
    Memo& memo = memo_[cls];
    count_lookup(cls);
    if (memo.valid && !memo.transient && memo.path == key.path) {  // the common case: no hashing
      ++hits_;
      if (memo.stamp != epoch_ || epoch_ == 0) {
        memo.it->stamp = memo.stamp = epoch_;
        if (memo.it != lru_.begin() && half_full(g)) lru_.splice(lru_.begin(), lru_, memo.it);
      }
      return memo.e;
    }
    return lookup(g, key);
  }
  const GraphExpansion* lookup(const GraphClasses& g, const CacheKey& key);  // get() past the memo
  void view(const GraphClasses& g, GraphExpansion* e, uint32_t cls, uint64_t path);
  bool admit(const GraphClasses& g, uint32_t cls, size_t bytes) const;
  void count_lookup(uint32_t cls) {
    ++memo_[cls].freq;
    if (++lookups_ >= 16 * uint64_t(memo_.size())) {
      for (Memo& m : memo_) m.freq >>= 1;
      lookups_ = 0;
    }
  }
  // Recency is kept (entries moved to the front of the list) only once the
  // cache is half full: below that nothing is evicted soon; the entries
  // touched meanwhile keep their insertion order.
  bool half_full(const GraphClasses& g) const {
    return (g.opt.cache_entries && 2 * lru_.size() >= g.opt.cache_entries) ||
           (g.opt.cache_bytes && 2 * bytes_ >= g.opt.cache_bytes);
  }
  bool over(const GraphClasses& g) const;
  void trim(const GraphClasses& g);

  std::list<Entry> lru_;  // front: most recently used
  std::unordered_map<CacheKey, std::list<Entry>::iterator, CacheKeyHash> map_;
  std::vector<Memo> memo_;
  // Expansions that a full cache did not admit: held until the traversal ends.
  std::vector<std::pair<uint32_t, std::shared_ptr<const GraphExpansion>>> transient_;
  uint64_t lookups_ = 0;                    // since the frequencies were last halved
  size_t bytes_ = 0, peak_ = 0;
  uint64_t hits_ = 0, misses_ = 0, evictions_ = 0, bypassed_ = 0;
  uint64_t epoch_ = 0, tick_ = 0;           // the running traversal (0: none), the last one
  ViewScratch scratch_;
};

}  // namespace plm::lsystem
