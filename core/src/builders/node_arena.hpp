// The pointer tree's storage: build nodes and their leaves' lists, carved
// out of large blocks that live until the tree is flattened.
//
// Why: a kd build makes about as many nodes as it has references (1.2 M for
// conference), each leaf with its own lists. Taken from malloc one by one
// they cost about a tenth of the build (malloc in the build, free after the
// flattening, the pointer chasing of nodes scattered over the heap); from
// the arena they are a pointer bump each, lie in the order they were made
// (the flattening's walk order), and go back in a few hundred frees.
#pragma once
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <new>
#include <type_traits>
#include <vector>

namespace bsp {

class NodeArena {
public:
    // Blocks of this size hold many nodes; an array of more than a quarter
    // of it gets a block of its own, so a block wastes at most a quarter.
    static constexpr size_t kBlockBytes = size_t(1) << 20;

    NodeArena() = default;
    NodeArena(const NodeArena&) = delete;
    NodeArena& operator=(const NodeArena&) = delete;

    // One build task's allocator (used by that task's thread only): it
    // carves its current block alone and takes a new block from the arena,
    // under the arena's lock, when the block is full.
    class Local {
    public:
        explicit Local(NodeArena& arena) : arena_(&arena) {}
        Local(const Local&) = delete;
        Local& operator=(const Local&) = delete;

        // A value-initialised T (T must not need destruction: the arena
        // never runs destructors).
        template <class T>
        T* make() {
            static_assert(std::is_trivially_destructible_v<T>);
            return new (take(sizeof(T), alignof(T))) T();
        }

        // Room for n T's, uninitialised (nullptr for none).
        template <class T>
        T* array(size_t n) {
            static_assert(std::is_trivially_destructible_v<T>);
            return n ? static_cast<T*>(take(n * sizeof(T), alignof(T))) : nullptr;
        }

    private:
        void* take(size_t bytes, size_t align) {
            uintptr_t p = (reinterpret_cast<uintptr_t>(next_) + (align - 1)) & ~uintptr_t(align - 1);
            if (!next_ || p + bytes > reinterpret_cast<uintptr_t>(end_)) {
                if (bytes > kBlockBytes / 4) return arena_->block(bytes);
                next_ = arena_->block(kBlockBytes);
                end_ = next_ + kBlockBytes;
                p = (reinterpret_cast<uintptr_t>(next_) + (align - 1)) & ~uintptr_t(align - 1);
            }
            next_ = reinterpret_cast<char*>(p + bytes);
            return reinterpret_cast<void*>(p);
        }

        NodeArena* arena_;
        char* next_ = nullptr;
        char* end_ = nullptr;
    };

private:
    // operator new[]'s blocks are aligned for any fundamental type.
    char* block(size_t bytes) {
        std::unique_ptr<char[]> b(new char[bytes]);
        std::lock_guard<std::mutex> lock(mutex_);
        blocks_.push_back(std::move(b));
        return blocks_.back().get();
    }

    std::mutex mutex_;
    std::vector<std::unique_ptr<char[]>> blocks_;
};

}  // namespace bsp
