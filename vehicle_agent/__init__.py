"""What makes one vehicle its own process? vehicle_agent.agent (the process and its public door) and its
rooms, each a module opening with the question it answers (docs/architecture.md, "The agent")."""
