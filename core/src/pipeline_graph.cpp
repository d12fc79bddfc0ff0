// The graph of a pipeline: the order blocks run in (io reads, the rest topologically, io
// writes), the arena every output lives in, and the list of operations of one cycle.
#include "lode/sdk/clock.hpp"
#include "lode/config_file.hpp"
#include "lode/pipeline.hpp"

#include <arpa/inet.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <cstring>
#include <fstream>
#include <limits>
#include <deque>
#include <map>
#include <set>
#include <sstream>

#include "lode/telemetry.hpp"
#include "lode/sdk/units.hpp"
#include "params_node.hpp"
#include "pipeline_impl.hpp"
#include "port_binder.hpp"
#include "yaml_document.hpp"

namespace lode {

using namespace pipeline_detail;

std::vector<BlockEntry*> Pipeline::Impl::order_blocks() {
  // io blocks are sources (read phase) and sinks (write phase): edges into them never
  // constrain the order, so feedback through the plant is not a cycle.
  std::vector<BlockEntry*> io, rest;
  std::vector<BlockEntry*> feeds;
  std::vector<BlockEntry*> shadows;  // configured after everything else, not in the cycle order
  for (auto& b : blocks) {
    if (!b->shadow_of.empty()) { shadows.push_back(b.get()); continue; }
    (!b->plugin.descriptor && b->configured ? feeds : b->is_io() ? io : rest).push_back(b.get());
  }
  std::map<BlockEntry*, std::set<BlockEntry*>> deps;  // block -> non-io blocks it reads
  for (auto* b : rest) {
    deps[b];
    for (const auto& w : b->wiring) {
      BlockEntry* src = find_block(w.src_block);
      if (src && !src->is_io() && src->block == nullptr && src->configured) continue;  // feed
      if (src && !src->is_io() && src != b) deps[b].insert(src);
      if (src == b) error(w.where, "blocks." + b->name + ".inputs." + w.input,
                          "block '" + b->name + "' reads its own output: algebraic loop");
    }
  }
  std::vector<BlockEntry*> order = io;
  std::set<BlockEntry*> placed(io.begin(), io.end());
  placed.insert(feeds.begin(), feeds.end());
  bool progress = true;
  while (progress) {
    progress = false;
    for (auto* b : rest) {  // file order breaks ties: the order a person wrote is kept
      if (placed.count(b)) continue;
      bool ready = true;
      for (auto* d : deps[b]) ready = ready && placed.count(d);
      if (ready) {
        order.push_back(b);
        placed.insert(b);
        progress = true;
      }
    }
  }
  if (order.size() + feeds.size() + shadows.size() != blocks.size()) {
    std::string names;
    BlockEntry* first = nullptr;
    for (auto* b : rest)
      if (!placed.count(b)) {
        names += (names.empty() ? "" : ", ") + b->name;
        if (!first) first = b;
      }
    SourceLocation where = first ? first->where : SourceLocation{file, 0, 0};
    if (first)
      for (const auto& w : first->wiring) {
        BlockEntry* src = find_block(w.src_block);
        if (src && !placed.count(src) && !src->is_io()) { where = w.where; break; }
      }
    error(where, "blocks", "cycle among blocks: " + names +
                               " (only io blocks may close a loop: they read at the start of "
                               "the cycle and write at its end)");
    for (auto* b : rest)
      if (!placed.count(b)) order.push_back(b);  // still configure them to find more problems
  }
  order.insert(order.end(), shadows.begin(), shadows.end());
  return order;
}


void Pipeline::Impl::allocate_and_bind() {
  std::size_t total = 0;
  for (auto& b : blocks)
    for (auto& o : b->outputs) {
      o.offset = total;
      total += o.elements.size();
    }
  // One allocation for every signal of the pipeline; never resized afterwards, so the
  // pointers handed to the blocks stay valid for the pipeline's lifetime.
  arena.assign(total, 0.0);
  for (auto& b : blocks) {
    for (auto& o : b->outputs) PortBinder::bind(*o.port, arena.data() + o.offset, o.elements.size());
    b->live.store(b.get(), std::memory_order_relaxed);
  }
  for (auto& b : blocks) bind_inputs(*b, arena.data());
}

void Pipeline::Impl::bind_inputs(BlockEntry& record, const double* storage) {
  for (auto& d : record.inputs)
    for (const auto& w : record.wiring) {
      if (w.input != d.name) continue;
      const BlockEntry* src = find_block(w.src_block);
      const DeclaredOutput* out = src ? src->output(w.src_port) : nullptr;
      if (out) PortBinder::bind(*d.port, storage + out->offset, out->elements.size());
    }
}


void Pipeline::Impl::build_ops(const std::vector<BlockEntry*>& order) {
  for (auto* b : order) {
    if (!b->block || !b->shadow_of.empty()) continue;
    Op op;
    op.block = b->block.get();
    op.label = b->is_io() ? b->name + ".read" : b->name;
    op.exec_time = std::make_unique<Histogram>();
    ops.push_back(std::move(op));
  }
  for (auto* b : order) {
    if (!b->block || !b->is_io()) continue;
    Op op;
    op.block = b->block.get();
    op.board = b->board;
    op.label = b->name + ".write";
    op.write_phase = true;
    op.exec_time = std::make_unique<Histogram>();
    ops.push_back(std::move(op));
  }
}

}  // namespace lode
