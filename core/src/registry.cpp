#include "registry.hpp"

#include <algorithm>
#include <cmath>
#include <cctype>
#include <stdexcept>
#include <type_traits>

#include <unistd.h>

#include "builders/bsp_build.hpp"
#include "builders/bvh_build.hpp"
#include "builders/kd_build.hpp"
#include "instanced.hpp"

namespace bsp {

namespace {

// The default memory limit of a build: this share of the machine's physical
// memory (sysconf), so that a big machine builds big flat scenes and a
// small one stops before it swaps; kFallbackMemoryMb where the system does
// not say.
constexpr double kMemoryShare = 0.5;
constexpr double kFallbackMemoryMb = 4096.0;

double default_memory_limit_mb() {
    const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
    if (pages <= 0 || page <= 0) return kFallbackMemoryMb;
    return std::floor(kMemoryShare * double(pages) * double(page) / (1024.0 * 1024.0));
}

// ---- Setting BuildOptions fields from OptionValues -------------------------

// The messages here complete "option NAME ..." (options_for() adds the name).
template <class T>
T as_number(const OptionValue& v) {
    if (const int64_t* i = std::get_if<int64_t>(&v)) return T(*i);
    if (const double* d = std::get_if<double>(&v)) {
        // A real number for a whole-number field would be truncated silently.
        if (std::is_integral_v<T> && *d != double(T(*d)))
            throw std::invalid_argument("takes a whole number");
        return T(*d);
    }
    throw std::invalid_argument("takes a number, not a string");
}

const std::string& as_string(const OptionValue& v) {
    if (const std::string* s = std::get_if<std::string>(&v)) return *s;
    throw std::invalid_argument("takes a string");
}

// The setter of a plain numeric field, by member pointer.
template <auto Field>
void set_field(BuildOptions& o, const OptionValue& v) {
    using T = std::remove_reference_t<decltype(o.*Field)>;
    o.*Field = as_number<T>(v);
}

void set_leaf_boxes(BuildOptions& o, const OptionValue& v) {
    const std::string& s = as_string(v);
    if (s == "none") o.leaf_boxes = LeafBoxes::None;
    else if (s == "triangle") o.leaf_boxes = LeafBoxes::Triangle;
    else if (s == "clipped") o.leaf_boxes = LeafBoxes::Clipped;
    else throw std::invalid_argument("must be none, triangle or clipped, got " + s);
}

void set_build_quality(BuildOptions& o, const OptionValue& v) {
    const std::string& s = as_string(v);
    if (s == "exact") o.build_quality = BuildQuality::Exact;
    else if (s == "fast") o.build_quality = BuildQuality::Fast;
    else throw std::invalid_argument("must be exact or fast, got " + s);
}

const std::vector<int> kDopSizes = {3, 7, 9, 13};

// RBSP's set; "auto" takes the k-DOP set where one exists for K, else the
// three axes plus K - 3 spiral points. Needs K set first (option order).
void set_rbsp_set(BuildOptions& o, const OptionValue& v) {
    std::string s = as_string(v);
    if (s == "auto")
        s = std::count(kDopSizes.begin(), kDopSizes.end(), o.k) ? "dop" : "axes+spiral";
    if (s == "spiral") o.fixed_set = 0;
    else if (s == "dop") o.fixed_set = 1;
    else if (s == "axes+spiral") o.fixed_set = 2;
    else throw std::invalid_argument("must be auto, spiral or dop, got " + s);
}

// The setter of a numeric TopLevelSettings field, by member pointer.
template <auto Field>
void set_top_field(TopLevelSettings& s, const OptionValue& v) {
    using T = std::remove_reference_t<decltype(s.*Field)>;
    s.*Field = as_number<T>(v);
}

// The name, field and setter of an option that sets the numeric field of its name.
#define NUMBER_FIELD(f) .name = #f, .field = #f, .apply = set_field<&BuildOptions::f>
// The same for the top level's option top_F, setting TopLevelSettings's F.
#define TOP_FIELD(f) .name = "top_" #f, .field = #f, .apply_top = set_top_field<&TopLevelSettings::f>

OptionValue whole(int64_t v) { return OptionValue(v); }
OptionValue real(double v) { return OptionValue(v); }

std::vector<OptionSpec> make_option_specs() {
    using T = OptionType;
    // Limits are written as today's checks wrote them (whole or real), so
    // their messages print them the same way.
    return {
        {NUMBER_FIELD(traversal_cost), .type = T::Float, .group = "common",
         .default_value = real(1.0), .min = whole(0), .max = real(1e6), .min_open = true,
         .soft_max = 10.0, .label = "Traversal Cost", .short_label = "Traversal",
         .help = "SAH cost of visiting one interior node (K_d; every step without ^Kd)"},
        {NUMBER_FIELD(intersect_cost), .type = T::Float, .group = "common",
         .default_value = real(1.5), .min = whole(0), .max = real(1e6), .min_open = true,
         .soft_max = 10.0, .label = "Intersection Cost", .short_label = "Intersection",
         .help = "SAH cost of one ray-triangle test (K_i)"},
        {NUMBER_FIELD(empty_bonus), .type = T::Float, .group = "common", .default_value = real(0.2),
         .min = whole(0), .max = real(0.99), .label = "Empty Bonus", .short_label = "Empty",
         .help = "SAH discount for splits that cut off empty space"},
        {NUMBER_FIELD(max_depth), .type = T::Int, .group = "common", .default_value = whole(0),
         .min = whole(0), .max = whole(64), .label = "Max Depth", .short_label = "Max Depth",
         .help = "Maximum tree depth (0: automatic, 8 + 1.3 log2 N)"},
        {NUMBER_FIELD(leaf_size), .type = T::Int, .group = "common", .default_value = whole(1),
         .min = whole(1), .max = whole(1 << 20), .soft_max = 64, .label = "Leaf Size",
         .short_label = "Leaf Size",
         .help = "Stop splitting nodes with at most this many triangles"},
        {NUMBER_FIELD(max_duplication), .type = T::Float, .group = "common",
         .default_value = real(8.0), .min = whole(1), .max = whole(1000), .soft_max = 32.0,
         .label = "Max Duplication", .short_label = "Duplication",
         .help = "Stop splitting when triangle references exceed this multiple of the triangles"},
        {NUMBER_FIELD(memory_limit_mb), .type = T::Float, .group = "common",
         .default_value = real(default_memory_limit_mb()), .min = whole(0), .min_open = true,
         .label = "Memory Limit (MB)", .short_label = "Memory",
         .help = "The build stops with a MemoryError beyond this many megabytes "
                 "(default: half the machine's physical memory)"},
        {NUMBER_FIELD(threads), .apply_top = set_top_field<&TopLevelSettings::threads>,
         .type = T::Int, .group = "common", .default_value = whole(0),
         .min = whole(0), .max = whole(1024), .soft_max = 64, .label = "Threads",
         .short_label = "Threads", .help = "Worker threads of the core (0: all cores)"},
        {.name = "leaf_boxes", .field = "leaf_boxes", .apply = set_leaf_boxes,
         .type = T::Enum, .group = "common",
         .default_value = OptionValue("triangle"),
         .choices = {{"none", "None", "No boxes: leaf culling is not possible", {}},
                     {"triangle", "Triangle",
                      "Each triangle's own box (24 bytes per triangle)", {}},
                     {"clipped", "Clipped",
                      "Each reference's box clipped to its leaf cell (24 bytes per reference; "
                      "culls more)", {}}},
         .label = "Leaf Boxes", .short_label = "Leaf Boxes",
         .help = "Boxes kept for leaf culling with the ray segment's box"},
        // The build quality of kd and the sweep builder (every method but the BVH).
        {.name = "build_quality", .field = "build_quality", .apply = set_build_quality,
         .type = T::Enum, .group = "bsp", .default_value = OptionValue("exact"),
         .choices = {{"exact", "Exact",
                      "Every candidate plane swept at every node: the thesis's trees", {}},
                     {"fast", "Fast",
                      "Big nodes choose among binned planes, small ones sweep exactly: a quicker "
                      "build of a slightly costlier tree, for previews", {}}},
         .label = "Build Quality", .short_label = "Quality",
         .help = "How thoroughly each node looks for its plane (fast: binned SAH near the root)"},
        {NUMBER_FIELD(fast_bins), .type = T::Int, .group = "bsp", .default_value = whole(kFastBins),
         .min = whole(2), .max = whole(4096), .soft_max = 4096, .label = "Fast Bins",
         .short_label = "Fast Bins",
         .help = "Fast builds: bins per direction at a binned node (a sweep node of n "
                 "references at most 4 + n / 128)"},
        {NUMBER_FIELD(fast_min_refs), .type = T::Int, .group = "bsp",
         .default_value = whole(kFastMinRefs), .min = whole(2), .max = whole(INT32_MAX),
         .soft_max = 1 << 20, .label = "Fast Binned Size", .short_label = "Binned From",
         .help = "Fast builds: nodes with at least this many references are binned, smaller "
                 "ones swept exactly"},
        {NUMBER_FIELD(fast_min_gain), .type = T::Float, .group = "bsp",
         .default_value = real(kFastMinGain), .min = whole(0), .max = real(0.9),
         .label = "Fast Split Gain", .short_label = "Min Gain",
         .help = "Fast builds: a node splits only if that saves at least this share of its "
                 "leaf's cost (0: wherever it saves anything, as exact builds do)"},
        {NUMBER_FIELD(fast_clip_min_refs), .type = T::Int, .group = "bsp",
         .default_value = whole(kFastClipMinRefs), .min = whole(0), .max = whole(INT32_MAX),
         .soft_max = 256, .label = "Fast Clip Size", .short_label = "Clip From",
         .help = "Fast kd builds: a split whose children hold fewer references cuts the boxes "
                 "of the triangles it crosses at the plane instead of clipping the triangles "
                 "(0: clip everywhere, as exact builds do)"},
        // The BSP family. K's limits here are the widest; a method narrows
        // them (MethodSpec::min_k, max_k).
        {NUMBER_FIELD(k), .type = T::Int, .group = "bsp", .default_value = whole(6),
         .min = whole(1), .max = whole(kMaxK), .per_method_limits = true, .label = "K",
         .short_label = "K", .help = "Number of split directions tried per node"},
        {NUMBER_FIELD(seed), .type = T::Int, .group = "bsp", .default_value = whole(1),
         .min = whole(0), .max = whole(INT64_MAX),
         .label = "Seed", .short_label = "Seed",
         .help = "Seed of the random choices of randomised methods"},
        // The ^Kd costs: Ize et al. (2008) price a general node at
        // alpha * K_i * (n - 1) + K_d with alpha = 0.1, and fall back to a
        // constant K_d,BSP; general_cost = 1.4 K_d is what `calibrate`
        // measured for a general step of our traversal (K_gen/K_kd 1.35-1.40
        // over three runs; docs/algorithms.md "Costs").
        {NUMBER_FIELD(alpha), .type = T::Float, .group = "bsp", .default_value = real(0.1),
         .min = whole(0), .max = real(1e3), .soft_max = 1.0, .label = "Alpha",
         .short_label = "Alpha",
         .help = "Per-triangle factor of a general (non-axis) node's traversal cost"},
        {NUMBER_FIELD(general_cost), .type = T::Float, .group = "bsp", .default_value = real(1.4),
         .min = whole(0), .max = real(1e6), .min_open = true, .soft_max = 10.0,
         .label = "General Cost", .short_label = "General",
         .help = "Traversal cost of a general (non-axis) node"},
        {.name = "rbsp_set", .field = "fixed_set", .apply = set_rbsp_set,
         .type = T::Enum, .group = "bsp", .default_value = OptionValue("auto"),
         .choices = {{"auto", "Auto",
                      "k-DOP directions for K = 3, 7, 9, 13, else the axes plus a golden spiral",
                      {}},
                     {"spiral", "Spiral", "K directions on a golden spiral", {}},
                     {"dop", "k-DOP", "The k-DOP directions (K = 3, 7, 9 or 13)", kDopSizes}},
         .label = "Directions", .short_label = "Directions",
         .help = "The fixed direction set of RBSP"},
        {NUMBER_FIELD(cluster_iterations), .type = T::Int, .group = "bsp",
         .default_value = whole(16), .min = whole(1), .max = whole(500),
         .label = "Cluster Iterations", .short_label = "Iterations",
         .help = "k-means iterations for clustering the node's normals"},
        {NUMBER_FIELD(cluster_sample), .type = T::Int, .group = "bsp", .default_value = whole(1024),
         .min = whole(1), .max = whole(1 << 24), .soft_max = 65536, .label = "Cluster Sample",
         .short_label = "Sample", .help = "Normals sampled per node for the clustering"},
        {NUMBER_FIELD(ize_candidates), .type = T::Int, .group = "bsp", .default_value = whole(64),
         .min = whole(1), .max = whole(1 << 20), .soft_max = 4096, .label = "IZE Candidates",
         .short_label = "Candidates",
         .help = "Triangles whose own and edge planes are tried per node at most"},
        // The BVH's own. (Group "bsp" means "the methods that list it": the
        // BVH lists bins.)
        {NUMBER_FIELD(bins), .type = T::Int, .group = "bsp", .default_value = whole(kBvhBins),
         .min = whole(kBvhMinBins), .max = whole(kBvhMaxBins), .soft_max = 64, .label = "Bins",
         .short_label = "Bins",
         .help = "Centroid bins per axis of the BVH's binned SAH (a node of n triangles uses at "
                 "most 4 + n / 20)"},
        // An instanced scene's top level (build_instanced): the binned SAH of
        // its BVH over the instances' boxes, with a bottom trace priced as
        // an intersection. No method lists them.
        {TOP_FIELD(bins), .type = T::Int, .group = "top", .default_value = whole(kTopBins),
         .min = whole(kBvhMinBins), .max = whole(kBvhMaxBins), .soft_max = 64,
         .label = "Top Bins", .short_label = "Top Bins",
         .help = "Centroid bins per axis of the top level's binned SAH over the instances"},
        {TOP_FIELD(traversal_cost), .type = T::Float, .group = "top",
         .default_value = real(kTopTraversalCost), .min = whole(0), .max = real(1e6),
         .min_open = true, .soft_max = 10.0, .label = "Top Traversal Cost",
         .short_label = "Top Traversal", .help = "SAH cost of visiting one top-level node"},
        {TOP_FIELD(intersect_cost), .type = T::Float, .group = "top",
         .default_value = real(kTopIntersectCost), .min = whole(0), .max = real(1e6),
         .min_open = true, .soft_max = 20.0, .label = "Top Instance Cost",
         .short_label = "Top Instance",
         .help = "SAH cost of entering one instance (a whole mesh-tree trace, several box "
                 "steps: more than a triangle test)"},
    };
}

#undef TOP_FIELD
#undef NUMBER_FIELD

// ---- The builders -------------------------------------------------------------

const Builder kKdBuilder{"kd", build_kd_tree, false};
const Builder kSweepBuilder{"bsp", build_bsp_tree, true};
const Builder kBvhBuilder{"bvh", build_bvh_tree, false, Structure::Bvh};

// ---- The methods -------------------------------------------------------------

using Options = std::vector<std::string>;

Options operator+(Options a, const Options& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
}

// The build quality's options: kd's and the sweep builder's, not the BVH's.
const Options kQuality = {"build_quality", "fast_bins", "fast_min_refs", "fast_min_gain"};
const Options kSweepOptions = Options{"k", "seed"} + kQuality;
const Options kKdCosts = {"alpha", "general_cost"};


std::string lower(std::string s) {
    for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

// A direction strategy as plain, "+" (axes included) and "+kd" (^Kd) methods.
void add_family(std::vector<MethodSpec>& out, const std::string& base, const std::string& label,
                const std::string& what, const std::string& strategy, const Options& options,
                int64_t k_default) {
    const std::vector<std::pair<std::string, OptionValue>> k = {{"k", whole(k_default)}};
    out.push_back(
        {base, label, what + " at every node.", kSweepBuilder, strategy, false, false, options, k});
    out.push_back({base + "+", label + "+", "The three axes plus " + lower(what) + ".",
                   kSweepBuilder, strategy, true, false, options, k});
    out.push_back({base + "+kd", label + "+ ^Kd",
                   "The three axes plus " + lower(what) + "; axis splits are fast kd nodes.",
                   kSweepBuilder, strategy, true, true, options + kKdCosts, k});
}

std::vector<MethodSpec> make_method_specs() {
    std::vector<MethodSpec> m;
    m.push_back({"kd", "kd (SAH)",
                 "Axis-aligned kd-tree, SAH with perfect splits, O(N log N) build "
                 "(Wald & Havran 2006).",
                 kKdBuilder, "axes", false, false, kQuality + Options{"fast_clip_min_refs"}});
    m.push_back({"rbsp", "RBSP",
                 "Restricted BSP: one fixed set of K directions (k-DOP for K = 3, 7, 9, 13, "
                 "else the three axes plus K - 3 golden-spiral points) at every node.",
                 kSweepBuilder, "fixed", false, false, kSweepOptions + Options{"rbsp_set"},
                 {{"k", whole(13)}}});
    m.push_back({"rbsp+kd", "RBSP ^Kd", "RBSP whose axis splits are fast kd nodes.", kSweepBuilder,
                 "fixed", false, true, kSweepOptions + Options{"rbsp_set"} + kKdCosts,
                 {{"k", whole(13)}}});
    add_family(m, "bsp_random", "BSP random", "K random directions, fresh", "random",
               kSweepOptions, 10);
    add_family(m, "bsp_wn", "BSP wn", "The normals of K random triangles of the node", "normals",
               kSweepOptions, 6);
    add_family(m, "bsp_cn", "BSP cn",
               "K cluster centres (antipodal spherical k-means) of the node's normals",
               "clustered", kSweepOptions + Options{"cluster_iterations", "cluster_sample"}, 6);
    m.push_back({"bsp_ize", "BSP IZE",
                 "kd planes plus every triangle's own plane and its three edge planes "
                 "(Ize, Wald & Parker 2008).",
                 kSweepBuilder, "ize", true, false, Options{"seed", "ize_candidates"} + kQuality});
    m.push_back({"bsp_ize+kd", "BSP IZE ^Kd", "BSP_IZE whose axis splits are fast kd nodes.",
                 kSweepBuilder, "ize", true, true,
                 Options{"seed", "ize_candidates"} + kQuality + kKdCosts});
    m.push_back({"bvh", "BVH (binned SAH)",
                 "Binary bounding-volume hierarchy over the triangles' boxes, binned SAH "
                 "(Wald 2007): the structure of production renderers, traced by this kernel.",
                 kBvhBuilder, "axes", false, false, {"bins"},
                 // Its own triangle-test cost: with 8-wide nodes the walk's
                 // step is cheap beside a leaf's tests, and larger leaves
                 // than kd's cost of 1.5 makes pay (random rays 1.50-1.58x
                 // Embree's time with 1.5, 1.46-1.50x with 0.75, primary
                 // rays the same or better; docs/performance.md, "The BVH").
                 {{"intersect_cost", real(0.75)}}});
    return m;
}

template <class Spec>
const Spec& find_by_name(const std::vector<Spec>& specs, const std::string& name,
                         const char* what) {
    for (const Spec& s : specs)
        if (s.name == name) return s;
    std::string known;
    for (const Spec& s : specs) known += (known.empty() ? "" : ", ") + s.name;
    throw std::invalid_argument("unknown " + std::string(what) + " " + name + "; known: " + known);
}

}  // namespace

const std::vector<OptionSpec>& option_specs() {
    static const std::vector<OptionSpec> specs = make_option_specs();
    return specs;
}

const std::vector<MethodSpec>& method_specs() {
    static const std::vector<MethodSpec> specs = make_method_specs();
    return specs;
}

const OptionSpec& option_spec(const std::string& name) {
    return find_by_name(option_specs(), name, "option");
}

const MethodSpec& method_spec(const std::string& name) {
    return find_by_name(method_specs(), name, "method");
}

BuildOptions options_for(const MethodSpec& method,
                         const std::map<std::string, OptionValue>& values) {
    BuildOptions o;
    o.strategy = method.strategy;
    o.plus_axes = method.plus_axes;
    o.kd_nodes = method.kd_nodes;
    for (const auto& [name, value] : values)  // unknown names fail here
        if (!option_spec(name).apply)
            throw std::invalid_argument("option " + name + " is the top level's of an instanced "
                                        "scene (build_instanced), not a tree's");
    // The method's own defaults where `values` has none.
    std::map<std::string, OptionValue> with_defaults(method.defaults.begin(), method.defaults.end());
    for (const auto& [name, value] : values) with_defaults[name] = value;
    // In the specs' order: K before rbsp_set, which depends on it.
    for (const OptionSpec& spec : option_specs()) {
        const auto it = with_defaults.find(spec.name);
        if (it == with_defaults.end()) continue;
        try {
            spec.apply(o, it->second);
        } catch (const std::invalid_argument& e) {
            throw std::invalid_argument("option " + spec.name + " " + e.what());
        }
    }
    return o;
}

TopLevelSettings top_settings_for(const std::map<std::string, OptionValue>& values) {
    for (const auto& [name, value] : values) {
        if (option_spec(name).apply_top) continue;  // unknown names fail in option_spec
        std::string known;
        for (const OptionSpec& spec : option_specs())
            if (spec.apply_top) known += (known.empty() ? "" : ", ") + spec.name;
        throw std::invalid_argument("option " + name + " is not read by the top level; its "
                                    "options are " + known);
    }
    // Every field from the specs, their defaults where `values` has none.
    TopLevelSettings s;
    for (const OptionSpec& spec : option_specs()) {
        if (!spec.apply_top) continue;
        const auto it = values.find(spec.name);
        try {
            spec.apply_top(s, it == values.end() ? spec.default_value : it->second);
        } catch (const std::invalid_argument& e) {
            throw std::invalid_argument("option " + spec.name + " " + e.what());
        }
    }
    return s;
}

Tree build(const std::string& method, std::vector<Triangle> triangles,
           const std::map<std::string, OptionValue>& values, Progress* progress) {
    const MethodSpec& spec = method_spec(method);
    return spec.builder.build(std::move(triangles), options_for(spec, values), progress);
}

}  // namespace bsp
