// The one cost model of both builders: what a leaf costs, what a split costs,
// a cheap lower bound that prunes candidates, and the ^Kd prices of general
// steps. The kd builder (kd_build.cpp), the sweep builder (bsp_build.cpp) and
// the tree's reported SAH cost (build_tree.cpp) all read their costs here.
//
// The surface area heuristic (Goldsmith & Salmon 1987, MacDonald & Booth
// 1990) prices a node as the expected work of a ray that enters it: a split
// costs one traversal step plus, for each child, the probability a ray
// through the parent enters it (the ratio of surface areas, for uniformly
// distributed rays) times the triangles it would test there.
#pragma once
#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "tree.hpp"

namespace bsp {

class CostModel {
public:
    explicit CostModel(const BuildOptions& opt)
        : kd_step_(opt.traversal_cost),
          test_(opt.intersect_cost),
          empty_factor_(1.0f - opt.empty_bonus),
          kd_nodes_(opt.kd_nodes),
          alpha_(opt.alpha),
          general_fallback_(opt.general_cost),
          min_saving_per_ref_(opt.build_quality == BuildQuality::Fast
                                  ? opt.fast_min_gain * opt.intersect_cost
                                  : 0.0f) {}

    // A leaf tests every triangle it holds: K_i n.
    float leaf(size_t n) const { return test_ * float(n); }

    // What a split of a node of n references must cost less than. An exact
    // build splits wherever that beats the leaf. A fast one splits only
    // where it saves fast_min_gain of the leaf's cost, counting at most
    // kFastGainRefs references: deep nodes that save a few percent each are
    // most of an exact tree's nodes and little of its cost, while a big
    // node's small relative saving can still be many tests (tree.hpp,
    // kFastMinGain). Minus 0 for exact builds, so their trees are unchanged.
    float split_limit(size_t n) const {
        return leaf(n) - min_saving_per_ref_ * float(std::min(n, kFastGainRefs));
    }

    // The step cost of a kd node: K_d, one subtraction and one multiplication.
    float kd_step() const { return kd_step_; }

    // The step cost of a split node over n references. Without ^Kd every
    // step is K_d (the BSP papers price all nodes alike). Under ^Kd a general
    // step is priced alpha K_i (n - 1) + K_d after Ize et al. (2008): the
    // dearer a general plane, the more triangles it must save.
    float step(bool kd_node, size_t n) const {
        if (kd_node || !kd_nodes_) return kd_step_;
        return alpha_ * test_ * float(n - 1) + kd_step_;
    }

    // ^Kd: when no split beats the leaf at step(), the general planes are
    // tried again at this constant K_d,BSP (Ize et al.'s fallback); the
    // default 1.4 K_d is what `calibrate` measured a general step (two dot
    // products and a division) to cost against a kd step (one subtraction
    // and one multiplication). Only general candidates under ^Kd have it.
    bool has_fallback(bool kd_node) const { return kd_nodes_ && !kd_node; }
    float fallback_step() const { return general_fallback_; }

    // The SAH cost of a split with n_below and n_above references whose
    // parts a ray through the parent enters with probabilities p_below and
    // p_above (the parts' surface areas over the parent's):
    //   (step + K_i (p_below n_below + p_above n_above)) * bonus,
    // where the bonus (1 - empty_bonus) rewards cutting off empty space, as
    // in pbrt. Real is the caller's precision for the probabilities: float
    // for the kd builder's box areas, double for the sweep's cell areas; the
    // weighted count is rounded to float once, so each builder's trees are
    // what they were when the formula lived inside it.
    template <class Real>
    float split(float step, Real p_below, uint32_t n_below, Real p_above,
                uint32_t n_above) const {
        const float tests = float(p_below * Real(n_below) + p_above * Real(n_above));
        return (step + test_ * tests) * bonus(n_below == 0 || n_above == 0);
    }

    // A bound no split with at least n_below / n_above references on its
    // sides can beat: the parts' surfaces cover the parent's (and add the
    // cut twice), so p_below + p_above >= 1 and the weighted count is at
    // least min(n_below, n_above). A candidate whose bound does not beat the
    // best so far needs no areas. References lying in the plane may still
    // join either side: that only raises the true cost.
    float lower_bound(float step, uint32_t n_below, uint32_t n_above) const {
        const uint32_t fewer = std::min(n_below, n_above);
        return (step + test_ * float(fewer)) * bonus(fewer == 0);
    }

    // A finished node's term in the tree's SAH cost (stats["sah_cost"]),
    // given the probability p that a ray through the root enters it: a
    // leaf's tests, or a split node's step. General nodes under ^Kd count at
    // the constant K_d,BSP: the statistic compares trees, not candidates.
    double tree_term(double p, NodeKind kind, size_t refs) const {
        if (kind == NodeKind::Leaf) return p * test_ * double(refs);
        if (kind == NodeKind::General && kd_nodes_) return p * general_fallback_;
        return p * kd_step_;
    }

private:
    float bonus(bool one_side_empty) const { return one_side_empty ? empty_factor_ : 1.0f; }

    float kd_step_;           // K_d
    float test_;              // K_i
    float empty_factor_;      // 1 - empty_bonus
    bool kd_nodes_;           // ^Kd: kd and general steps are priced apart
    float alpha_;             // ^Kd: a general step's share of the tests it saves
    float general_fallback_;  // ^Kd: the constant K_d,BSP
    float min_saving_per_ref_;  // fast builds: K_i fast_min_gain (0: exact)
};

}  // namespace bsp
