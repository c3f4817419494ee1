// A tiny FlatBuffer writer for the tests of nn/tflite: tables, vectors and strings described as a
// tree, laid out parent first (every reference points forward, as a uoffset must), each node
// written once however often it is referenced, so tests can share objects on purpose. After
// build() every node knows its byte position, so a test can corrupt one field precisely.
// Also tiny_tflite(): a small hand-made model used by tests/nn/tflite_test.cpp and as fuzz seeds.
#pragma once
#include <cstdint>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace sl::test {

struct FbNode;
using FbPtr = std::shared_ptr<FbNode>;

struct FbNode {
  enum class Kind { Table, Scalars, Tables, String } kind = Kind::Table;
  std::vector<std::pair<int, std::string>> scalars;  // Table: field index -> little-endian bytes
  std::vector<std::pair<int, FbPtr>> refs;           // Table: field index -> referenced node
  std::string bytes;                                 // Scalars / String: element bytes
  uint32_t count = 0;                                // Scalars / String: element count
  std::vector<FbPtr> items;                          // Tables: elements
  size_t pos = 0;                                    // after build(): table start / vector length position

  template <class T>
  FbPtr scalar(int index, T v) {
    scalars.emplace_back(index, std::string(reinterpret_cast<const char*>(&v), sizeof(T)));
    return self();
  }
  FbPtr ref(int index, FbPtr child) {
    refs.emplace_back(index, std::move(child));
    return self();
  }
  FbPtr self() { return self_.lock(); }
  std::weak_ptr<FbNode> self_;
};

inline FbPtr fb_table() {
  auto n = std::make_shared<FbNode>();
  n->self_ = n;
  return n;
}

template <class T>
FbPtr fb_vec(const std::vector<T>& values) {
  FbPtr n = fb_table();
  n->kind = FbNode::Kind::Scalars;
  n->bytes.assign(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
  n->count = static_cast<uint32_t>(values.size());
  return n;
}

inline FbPtr fb_string(const std::string& s) {
  FbPtr n = fb_table();
  n->kind = FbNode::Kind::String;
  n->bytes = s;
  n->count = static_cast<uint32_t>(s.size());
  return n;
}

inline FbPtr fb_tables(std::vector<FbPtr> items) {
  FbPtr n = fb_table();
  n->kind = FbNode::Kind::Tables;
  n->items = std::move(items);
  return n;
}

// Serialises `root` after the 8-byte header (root uoffset, then the 4-byte identifier).
class FbWriter {
 public:
  std::string build(const FbPtr& root, const std::string& identifier = "TFL3") {
    out_.assign(8, '\0');
    std::memcpy(&out_[4], identifier.data(), std::min<size_t>(4, identifier.size()));
    pending_.push_back({0, root});
    while (!pending_.empty()) {
      auto [slot, node] = pending_.front();
      pending_.erase(pending_.begin());
      if (!written_.count(node.get())) written_[node.get()] = write(*node);
      put_u32(slot, static_cast<uint32_t>(written_[node.get()] - slot));
    }
    return out_;
  }

 private:
  void align(size_t a) { out_.append((a - out_.size() % a) % a, '\0'); }
  void put_u32(size_t at, uint32_t v) { std::memcpy(&out_[at], &v, 4); }
  void append_u32(uint32_t v) { out_.append(reinterpret_cast<const char*>(&v), 4); }
  void append_u16(uint16_t v) { out_.append(reinterpret_cast<const char*>(&v), 2); }

  size_t write(FbNode& n) {
    switch (n.kind) {
      case FbNode::Kind::Scalars:
      case FbNode::Kind::String:
        align(8);
        out_.append(4, '\0');  // keeps 8-byte elements 8-aligned
        n.pos = out_.size();
        append_u32(n.count);
        out_ += n.bytes;
        if (n.kind == FbNode::Kind::String) out_ += '\0';
        return n.pos;
      case FbNode::Kind::Tables: {
        align(4);
        n.pos = out_.size();
        append_u32(static_cast<uint32_t>(n.items.size()));
        for (const FbPtr& item : n.items) {
          pending_.push_back({out_.size(), item});
          append_u32(0);
        }
        return n.pos;
      }
      case FbNode::Kind::Table: break;
    }
    // The table's layout: soffset, then the references, then the scalars, each at its own offset.
    int max_index = -1;
    std::map<int, uint16_t> offsets;
    uint16_t at = 4;
    for (const auto& [i, c] : n.refs) {
      offsets[i] = at;
      at += 4;
      max_index = std::max(max_index, i);
    }
    for (const auto& [i, b] : n.scalars) {
      while (at % b.size() != 0) ++at;
      offsets[i] = at;
      at += static_cast<uint16_t>(b.size());
      max_index = std::max(max_index, i);
    }
    align(8);
    const size_t vtable = out_.size();
    append_u16(static_cast<uint16_t>(4 + 2 * (max_index + 1)));
    append_u16(at);
    for (int i = 0; i <= max_index; ++i) append_u16(offsets.count(i) ? offsets[i] : 0);
    align(8);
    n.pos = out_.size();
    const int32_t soffset = static_cast<int32_t>(n.pos - vtable);
    out_.append(at, '\0');
    std::memcpy(&out_[n.pos], &soffset, 4);
    for (const auto& [i, b] : n.scalars) std::memcpy(&out_[n.pos + offsets[i]], b.data(), b.size());
    for (const auto& [i, c] : n.refs) pending_.push_back({n.pos + offsets[i], c});
    return n.pos;
  }

  std::string out_;
  std::vector<std::pair<size_t, FbPtr>> pending_;  // (slot of a uoffset, node it must point at)
  std::map<const FbNode*, size_t> written_;
};

// A small TFLite model (schema field indices in the comments):
//   operator codes: 0 CONV_2D (deprecated_builtin_code 3, version 2), 1 custom "MyOp" (no version:
//   default 1), 2 code 150 (deprecated placeholder 127, builtin_code 150);
//   buffers: 0 empty, 1 six int8 weights, 2 two int32 biases, 3 empty;
//   tensors: 0 "input" (no type, no buffer: FLOAT32, buffer 0) [1, 4, 4, 3];
//            1 "w" INT8 [2, 1, 1, 3], per-channel scales {0.5, 0.25}, zero points {0, 1}, axis 0;
//            2 "b" INT32 [2], scale {0.125}; 3 "out" UINT8 [1, 2, 2, 2], scale 1/128, zero point 128;
//   operators: 0 CONV_2D (0, 1, 2) -> 3, VALID, stride 2 x 3, RELU, no dilation fields;
//              1 MyOp (3, -1) -> 0, no options; 2 code 150 (0) -> 3;
//   subgraph inputs {0}, outputs {3}; version 3; description "tiny".
struct TinyTflite {
  FbPtr model, tensors, buffers, operators, opcodes, subgraph;
  std::vector<FbPtr> tensor;  // the tensor tables
  std::string bytes;
};

inline TinyTflite tiny_tflite(const std::string& identifier = "TFL3") {
  TinyTflite t;
  auto buffer = [](const std::vector<uint8_t>& data) {
    FbPtr b = fb_table();
    if (!data.empty()) b->ref(0, fb_vec(data));
    return b;
  };
  const std::vector<int8_t> w = {-2, -1, 0, 1, 2, 3};
  const std::vector<int32_t> bias = {8, -16};
  std::vector<uint8_t> wb(w.size()), bb(8);
  std::memcpy(wb.data(), w.data(), w.size());
  std::memcpy(bb.data(), bias.data(), 8);
  t.buffers = fb_tables({buffer({}), buffer(wb), buffer(bb), buffer({})});

  auto quant = [](std::vector<float> scale, std::vector<int64_t> zero_point, int32_t axis) {
    FbPtr q = fb_table()->ref(2, fb_vec(scale))->ref(3, fb_vec(zero_point));
    if (axis) q->scalar<int32_t>(6, axis);
    return q;
  };
  t.tensor = {
      fb_table()->ref(0, fb_vec<int32_t>({1, 4, 4, 3}))->ref(3, fb_string("input")),
      fb_table()->ref(0, fb_vec<int32_t>({2, 1, 1, 3}))->scalar<int8_t>(1, 9)->scalar<uint32_t>(2, 1)
          ->ref(3, fb_string("w"))->ref(4, quant({0.5f, 0.25f}, {0, 1}, 0)),
      fb_table()->ref(0, fb_vec<int32_t>({2}))->scalar<int8_t>(1, 2)->scalar<uint32_t>(2, 2)
          ->ref(3, fb_string("b"))->ref(4, quant({0.125f}, {0}, 0)),
      fb_table()->ref(0, fb_vec<int32_t>({1, 2, 2, 2}))->scalar<int8_t>(1, 3)->scalar<uint32_t>(2, 3)
          ->ref(3, fb_string("out"))->ref(4, quant({1.0f / 128}, {128}, 0)),
  };
  t.tensors = fb_tables(t.tensor);

  t.opcodes = fb_tables({
      fb_table()->scalar<int8_t>(0, 3)->scalar<int32_t>(2, 2),
      fb_table()->scalar<int8_t>(0, 32)->ref(1, fb_string("MyOp")),
      fb_table()->scalar<int8_t>(0, 127)->scalar<int32_t>(3, 150),
  });
  FbPtr conv_options = fb_table()->scalar<int8_t>(0, 1)->scalar<int32_t>(1, 3)->scalar<int32_t>(2, 2)
                           ->scalar<int8_t>(3, 1);
  t.operators = fb_tables({
      fb_table()->ref(1, fb_vec<int32_t>({0, 1, 2}))->ref(2, fb_vec<int32_t>({3}))->scalar<uint8_t>(3, 1)
          ->ref(4, conv_options),
      fb_table()->scalar<uint32_t>(0, 1)->ref(1, fb_vec<int32_t>({3, -1}))->ref(2, fb_vec<int32_t>({0})),
      fb_table()->scalar<uint32_t>(0, 2)->ref(1, fb_vec<int32_t>({0}))->ref(2, fb_vec<int32_t>({3})),
  });
  t.subgraph = fb_table()->ref(0, t.tensors)->ref(1, fb_vec<int32_t>({0}))->ref(2, fb_vec<int32_t>({3}))
                   ->ref(3, t.operators)->ref(4, fb_string("main"));
  t.model = fb_table()->scalar<uint32_t>(0, 3)->ref(1, t.opcodes)->ref(2, fb_tables({t.subgraph}))
                ->ref(3, fb_string("tiny"))->ref(4, t.buffers);
  t.bytes = FbWriter().build(t.model, identifier);
  return t;
}

}  // namespace sl::test
