// The one table of tree methods and build options, and the one way in to
// building: build() finds the method by name, sets its options by name and
// runs its builder. Everything else reads the table: the bindings export it
// (_core.registry()), the Python package builds its method table and option
// checks from it, the Blender add-on its panel.
// A method is a builder (builders/builder.hpp) plus a direction strategy plus
// the options that apply; an option is a typed, limited BuildOptions field
// with help text.
#pragma once
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "builders/builder.hpp"
#include "builders/strategies/strategy.hpp"
#include "progress.hpp"
#include "tree.hpp"

namespace bsp {

struct TopLevelSettings;  // instanced.hpp: what the "top" group's options set

constexpr int kMaxK = 64;  // directions per node at most (each costs a sort and a sweep per node)

// An option's value as it crosses from Python: whole numbers stay exact
// (a seed may be up to 2^63 - 1, more than a double holds).
using OptionValue = std::variant<int64_t, double, std::string>;

enum class OptionType { Float, Int, Enum };

struct Choice {
    std::string name, label, help;
    std::vector<int> k_values;  // the K this choice needs; empty: any K
};

struct OptionSpec {
    std::string name;
    std::string field;  // the BuildOptions field it sets (a "top" option's: TopLevelSettings's)
    void (*apply)(BuildOptions&, const OptionValue&) = nullptr;  // none for a "top" option
    // The TopLevelSettings field it sets: the "top" options' and threads
    // (the top level's build takes the tree builds' thread count).
    void (*apply_top)(TopLevelSettings&, const OptionValue&) = nullptr;
    OptionType type = OptionType::Float;
    // "common": every method has it; "bsp": the methods that list it (BSP
    // family, BVH); "top": an instanced scene's top level (build_instanced),
    // no method's.
    std::string group;
    OptionValue default_value;
    // Closed limits unless min_open; none where the value is unbounded.
    // Kept as written (whole or real) so messages print them the same way.
    std::optional<OptionValue> min = {}, max = {};
    bool min_open = false;
    bool per_method_limits = false;  // K: min/max are the widest; see MethodSpec::min_k/max_k
    std::optional<double> soft_max = {};  // where a slider should end (the add-on)
    std::vector<Choice> choices = {};     // Enum only
    std::string label, short_label, help;
};

struct MethodSpec {
    std::string name, label, description;
    Builder builder;               // kd (Wald-Havran), bsp (the one sweep builder) or bvh
    std::string strategy = "axes"; // a name in strategy_names()
    bool plus_axes = false;        // "+": the three axes are among the K directions
    bool kd_nodes = false;         // ^Kd: axis splits stored and traversed as kd nodes
    std::vector<std::string> options = {};  // the "bsp" options that apply, beyond the common ones
    std::vector<std::pair<std::string, OptionValue>> defaults = {};  // the method's own defaults

    // A "+" method counts the three axes among its K, so it needs K >= 3.
    int min_k() const { return plus_axes ? 3 : 1; }
    int max_k() const { return kMaxK; }
    // Every interior node of its trees is a general node, so the traversal
    // step its traversal_cost prices is the general step (the measured
    // costs, bsplab/costs.py).
    bool all_general_nodes() const { return builder.general_nodes && !kd_nodes; }
};

// In order: the common options, the BSP family's, then the top level's. K
// comes before the options that depend on it (rbsp_set), which options_for()
// relies on.
const std::vector<OptionSpec>& option_specs();
const std::vector<MethodSpec>& method_specs();
// Throws std::invalid_argument naming the known ones.
const OptionSpec& option_spec(const std::string& name);
const MethodSpec& method_spec(const std::string& name);

// The method's BuildOptions with `values` (checked by the caller against the
// specs' limits; here only names and types are checked) set by name.
BuildOptions options_for(const MethodSpec& method,
                         const std::map<std::string, OptionValue>& values);

// The top level's settings (instanced.hpp) with `values` - the "top"
// options and threads, by name - set as options_for() sets a method's, the
// specs' defaults where `values` has none. Throws std::invalid_argument for
// an unknown name or one the top level does not read.
TopLevelSettings top_settings_for(const std::map<std::string, OptionValue>& values);

// The tree of method `method` over `triangles` (moved into the tree), with
// `values` set by option name as options_for() sets them: the one entry of
// every build from outside. Throws std::invalid_argument for an unknown
// method or option, and what the builder throws (builder.hpp).
Tree build(const std::string& method, std::vector<Triangle> triangles,
           const std::map<std::string, OptionValue>& values, Progress* progress);

}  // namespace bsp
