#include "builders/bvh_collapse.hpp"

#include <cassert>

namespace bsp {
namespace {

struct Collapser {
    const std::vector<BvhNode>& bin;
    std::vector<BvhWideNode>& out;
    std::vector<uint32_t>* binary_of;

    // Emits the wide node of binary interior node `b` and, below it, those of
    // its interior lanes; returns its index.
    uint32_t emit(uint32_t b) {
        uint32_t lanes[BvhWideNode::kWidth] = {bin[b].left(), bin[b].right()};
        int used = 2;
        while (used < BvhWideNode::kWidth) {
            int open = -1;
            float best = -1.0f;
            for (int l = 0; l < used; ++l) {
                const BvhNode& n = bin[lanes[l]];
                if (n.is_leaf()) continue;
                const float area = n.box().area();
                if (area > best) {
                    best = area;
                    open = l;
                }
            }
            if (open < 0) break;
            const uint32_t opened = lanes[open];
            lanes[open] = bin[opened].left();
            lanes[used++] = bin[opened].right();
        }
        const uint32_t index = uint32_t(out.size());
        out.push_back(BvhWideNode::empty());
        if (binary_of) {
            binary_of->resize(out.size() * BvhWideNode::kWidth, 0);
            for (int l = 0; l < used; ++l) (*binary_of)[index * BvhWideNode::kWidth + l] = lanes[l];
        }
        for (int l = 0; l < used; ++l) {
            const BvhNode& n = bin[lanes[l]];
            if (n.is_leaf()) {
                out[index].set(l, n.box(), n.first, n.count());
            } else {
                const uint32_t child = emit(lanes[l]);
                out[index].set(l, n.box(), child, BvhWideNode::kInterior);
            }
        }
        return index;
    }
};

}  // namespace

std::vector<BvhWideNode> collapse_bvh(const std::vector<BvhNode>& binary,
                                      std::vector<uint32_t>* binary_of) {
    std::vector<BvhWideNode> out;
    if (binary_of) binary_of->clear();
    if (binary.empty()) return out;
    if (binary[0].is_leaf()) {
        out.push_back(BvhWideNode::empty());
        out[0].set(0, binary[0].box(), binary[0].first, binary[0].count());
        if (binary_of) binary_of->assign(BvhWideNode::kWidth, 0);
        return out;
    }
    // About one wide node per kWidth - 1 binary interior nodes.
    out.reserve(binary.size() / (2 * (BvhWideNode::kWidth - 1)) + 1);
    if (binary_of) binary_of->reserve(out.capacity() * BvhWideNode::kWidth);
    Collapser{binary, out, binary_of}.emit(0);
    return out;
}

}  // namespace bsp
