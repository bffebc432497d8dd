// The table of direction strategies: the names BuildOptions::strategy takes,
// each with the factory of its file in this folder.
//
// They are listed here rather than registering themselves from static
// initialisers: the linker drops object files of a static library that
// nothing references, and with them such self-registration.
#include <stdexcept>

#include "builders/strategies/strategy.hpp"

namespace bsp {

std::unique_ptr<DirectionStrategy> make_axes_strategy(const BuildOptions&);
std::unique_ptr<DirectionStrategy> make_fixed_strategy(const BuildOptions&);
std::unique_ptr<DirectionStrategy> make_random_strategy(const BuildOptions&);
std::unique_ptr<DirectionStrategy> make_normals_strategy(const BuildOptions&);
std::unique_ptr<DirectionStrategy> make_clustered_strategy(const BuildOptions&);
std::unique_ptr<DirectionStrategy> make_ize_strategy(const BuildOptions&);

namespace {

struct StrategyEntry {
    const char* name;
    StrategyFactory make;
};

const StrategyEntry kStrategies[] = {
    {"axes", make_axes_strategy},          // kd: the three axes
    {"fixed", make_fixed_strategy},        // RBSP: one fixed set for the whole tree
    {"random", make_random_strategy},      // BSP_random(+): fresh random directions per node
    {"normals", make_normals_strategy},    // BSP_wn(+): normals of random triangles of the node
    {"clustered", make_clustered_strategy},// BSP_cn(+): k-means of the node's normals
    {"ize", make_ize_strategy},            // BSP_IZE: kd planes + each triangle's own planes
};

}  // namespace

std::vector<std::string> strategy_names() {
    std::vector<std::string> out;
    for (const StrategyEntry& s : kStrategies) out.push_back(s.name);
    return out;
}

std::unique_ptr<DirectionStrategy> make_strategy(const BuildOptions& options) {
    for (const StrategyEntry& s : kStrategies)
        if (options.strategy == s.name) return s.make(options);
    std::string known;
    for (const std::string& n : strategy_names()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument("unknown direction strategy " + options.strategy + "; known: " +
                                known);
}

}  // namespace bsp
