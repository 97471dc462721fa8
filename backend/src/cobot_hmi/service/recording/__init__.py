"""Layer: service. Every frame of every robot into its recording (cobot_hmi.history)."""
